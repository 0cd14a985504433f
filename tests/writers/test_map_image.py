"""The map writer: exact bytes, YAML that every loader reads right, and nothing half-written."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from gridmap_cli.errors import GridmapError, OutputExistsError, UsageError
from gridmap_cli.mapping.grid import GridSpec, OccupancyMap
from gridmap_cli.writers import map_image
from gridmap_cli.writers.map_image import (
    check_map_outputs,
    map_output_paths,
    map_pixels,
    write_map,
)

NAN = math.nan


def omap(
    prob: list[list[float]], x0: float = 0.0, y0: float = 0.0, res: float = 0.05
) -> OccupancyMap:
    """A map from rows listed bottom (map row 0) first."""
    arr = np.array(prob, dtype=np.float64)
    return OccupancyMap(GridSpec(x0, y0, res, arr.shape[1], arr.shape[0]), arr)


def load_yaml(path: Path) -> dict[str, object]:
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert isinstance(doc, dict)
    return doc


# --- paths and preconditions ---------------------------------------------------------------------


def test_output_paths_put_the_yaml_beside_the_image(tmp_path: Path) -> None:
    assert map_output_paths(tmp_path / "a" / "room.pgm") == (
        tmp_path / "a" / "room.pgm",
        tmp_path / "a" / "room.yaml",
    )
    assert map_output_paths(Path("room.v2.PNG"))[1] == Path("room.v2.yaml")


@pytest.mark.parametrize("name", ["room.jpg", "room", "room.yaml", "room.pgm.gz"])
def test_output_paths_refuse_other_suffixes(name: str) -> None:
    with pytest.raises(UsageError, match=r"\.pgm or \.png"):
        map_output_paths(Path(name))


def test_check_refuses_an_existing_image_or_yaml_without_force(tmp_path: Path) -> None:
    image, meta = tmp_path / "m.pgm", tmp_path / "m.yaml"
    check_map_outputs(image, "trinary", force=False)  # nothing there yet
    image.write_bytes(b"x")
    with pytest.raises(OutputExistsError, match=r"m\.pgm exists"):
        check_map_outputs(image, "trinary", force=False)
    image.unlink()
    meta.write_text("x")
    with pytest.raises(OutputExistsError, match=r"m\.yaml exists"):
        check_map_outputs(image, "trinary", force=False)
    check_map_outputs(image, "trinary", force=True)


def test_check_refuses_scale_in_a_pgm_and_unknown_modes(tmp_path: Path) -> None:
    with pytest.raises(UsageError, match="PNG"):
        check_map_outputs(tmp_path / "m.pgm", "scale", force=True)
    check_map_outputs(tmp_path / "m.png", "scale", force=False)
    with pytest.raises(UsageError, match="unknown map mode 'ternary'"):
        check_map_outputs(tmp_path / "m.png", "ternary", force=False)


def test_check_refuses_a_directory_even_with_force(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").mkdir()
    with pytest.raises(UsageError, match="is a directory"):
        check_map_outputs(tmp_path / "m.pgm", "trinary", force=True)


def test_write_refuses_existing_outputs_without_force(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").write_text("keep me")
    with pytest.raises(OutputExistsError):
        write_map(tmp_path / "m.pgm", omap([[0.0]]))
    assert (tmp_path / "m.yaml").read_text() == "keep me"
    assert not (tmp_path / "m.pgm").exists()


# --- pixels --------------------------------------------------------------------------------------


def test_trinary_pixels_follow_the_saver_thresholds() -> None:
    # p >= occupied -> 0, p <= free -> 254, between and never observed -> 205
    prob = np.array([[0.0, 0.25, 0.2500001, 0.5, 0.6499999, 0.65, 1.0, NAN]])
    assert map_pixels(prob, "trinary", 0.65, 0.25).tolist() == [
        [254, 254, 205, 205, 205, 0, 0, 205]
    ]


def test_pixels_are_top_row_first() -> None:
    prob = np.array([[1.0, 1.0], [0.0, 0.0], [NAN, 0.0]])  # map row 0 (bottom) is occupied
    assert map_pixels(prob, "trinary", 0.65, 0.25).tolist() == [[205, 254], [254, 254], [0, 0]]


def test_scale_pixels_are_grey_and_alpha() -> None:
    prob = np.array([[0.0, 0.5, 0.8, 1.0, NAN]])
    px = map_pixels(prob, "scale", 0.65, 0.25)
    assert px.shape == (1, 5, 2) and px.dtype == np.uint8
    # grey = round(255 (1 - p)): 255, 127.5 -> 128 (half to even), 51, 0
    assert px[0, :4, 0].tolist() == [255, 128, 51, 0]
    assert px[..., 1].tolist() == [[255, 255, 255, 255, 0]]


def test_scale_unknown_grey_lies_between_the_loading_thresholds() -> None:
    # ROS 1 looks at alpha only for pixels between the thresholds, so the grey under a
    # transparent pixel must be one of those, whatever the thresholds
    for occupied, free in [(0.65, 0.25), (0.65, 0.196), (0.9, 0.05), (0.31, 0.3)]:
        grey = int(map_pixels(np.array([[NAN]]), "scale", occupied, free)[0, 0, 0])
        p = (255 - grey) / 255
        assert free < p < occupied, (occupied, free, grey)


def test_raw_pixels_are_percentages_with_the_maps_classes_at_0_and_100() -> None:
    # occupied (p >= 0.65) is 100 and free (p <= 0.25) 0, the values Nav2's costmap and AMCL
    # read as a wall and as free; the rest round(100 p), half to even
    prob = np.array([[0.0, 0.25, 0.2501, 0.425, 0.6449, 0.65, 0.7, NAN]])
    assert map_pixels(prob, "raw", 0.65, 0.25).tolist() == [[0, 0, 25, 42, 64, 100, 100, 255]]
    # a cell between the thresholds never reads as free or as a wall, however it rounds
    prob = np.array([[0.004, 0.0051, 0.994, 0.995]])
    assert map_pixels(prob, "raw", 0.995, 0.005).tolist() == [[0, 1, 99, 100]]


def test_scale_walls_and_free_cells_load_as_such_under_strict_thresholds() -> None:
    # p = 0.65 rounds to grey 89 (p 0.651) but p = 0.6501 with occupied 0.6505 would round to a
    # grey below the threshold: a cell the map calls occupied gets a grey strictly beyond it
    for occupied, free in [(0.65, 0.25), (0.6505, 0.2), (0.7, 0.2), (0.9, 0.05)]:
        p = np.array([[occupied, occupied + 1e-4, free, free - 1e-4, 1.0, 0.0]])
        grey = map_pixels(np.minimum(p, 1.0), "scale", occupied, free)[0, :, 0].astype(int)
        loaded = (255 - grey) / 255
        assert (loaded[[0, 1, 4]] > occupied).all(), (occupied, grey)
        assert (loaded[[2, 3, 5]] < free).all(), (free, grey)


@pytest.mark.parametrize(
    ("occupied", "free"), [(0.5, 0.5), (0.4, 0.6), (1.1, 0.2), (0.6, -0.1), (NAN, 0.2)]
)
def test_pixels_refuse_bad_thresholds(occupied: float, free: float) -> None:
    with pytest.raises(UsageError, match="free threshold < occupied threshold"):
        map_pixels(np.zeros((2, 2)), "trinary", occupied, free)


def test_pixels_refuse_probabilities_outside_0_1() -> None:
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        map_pixels(np.array([[0.5, 1.5]]), "raw", 0.65, 0.25)


# --- files ---------------------------------------------------------------------------------------


def test_pgm_is_byte_exact_like_nav2s_saver(tmp_path: Path) -> None:
    # map rows bottom first; the file holds them top first: 205 0 254 / 254 254 0 / 0 205 254
    m = omap([[0.9, NAN, 0.1], [0.0, 0.2, 0.7], [0.4, 1.0, 0.25]])
    image, _ = write_map(tmp_path / "m.pgm", m)
    data = image.read_bytes()
    assert len(data) == 20
    assert data == b"P5\n3 3\n255\n" + bytes([205, 0, 254, 254, 254, 0, 0, 205, 254])


def test_yaml_text_is_exactly_predictable(tmp_path: Path) -> None:
    write_map(tmp_path / "m.pgm", omap([[0.0]], x0=-2.65, y0=1.5, res=0.05))
    assert (tmp_path / "m.yaml").read_text(encoding="utf-8") == (
        "image: m.pgm\n"
        "mode: trinary\n"
        "resolution: 0.05\n"
        "origin: [-2.65, 1.5, 0.0]\n"
        "negate: 0\n"
        "occupied_thresh: 0.65\n"
        "free_thresh: 0.196\n"
    )


def test_yaml_image_is_the_basename_when_written_into_a_subfolder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "maps").mkdir()
    _, meta = write_map(Path("maps/room.png"), omap([[0.0, 1.0]]))
    assert meta == Path("maps/room.yaml")
    assert load_yaml(tmp_path / "maps" / "room.yaml")["image"] == "room.png"
    assert Image.open(tmp_path / "maps" / "room.png").size == (2, 1)


def test_yaml_numbers_keep_full_precision(tmp_path: Path) -> None:
    write_map(tmp_path / "m.pgm", omap([[0.0]], x0=12345.123, y0=1e-05, res=0.025))
    text = (tmp_path / "m.yaml").read_text(encoding="utf-8")
    doc = load_yaml(tmp_path / "m.yaml")
    assert "12345.123" in text and "e+03" not in text
    origin = doc["origin"]
    assert origin == [12345.123, 1e-05, 0.0]
    assert isinstance(origin, list) and all(isinstance(v, float) for v in origin)  # not '1e-05'
    assert doc["resolution"] == 0.025
    assert "nan" not in text.lower()


def test_trinary_yaml_thresholds_are_always_0_65_and_0_196(tmp_path: Path) -> None:
    write_map(tmp_path / "m.pgm", omap([[0.5]]), occupied_thresh=0.8, free_thresh=0.3)
    doc = load_yaml(tmp_path / "m.yaml")
    assert (doc["occupied_thresh"], doc["free_thresh"]) == (0.65, 0.196)
    assert (doc["mode"], doc["negate"]) == ("trinary", 0)


@pytest.mark.parametrize(("mode", "suffix"), [("scale", ".png"), ("raw", ".pgm"), ("raw", ".png")])
def test_scale_and_raw_yaml_thresholds_are_the_given_ones(
    tmp_path: Path, mode: str, suffix: str
) -> None:
    write_map(
        tmp_path / f"m{suffix}", omap([[0.5]]), mode=mode, occupied_thresh=0.7, free_thresh=0.2
    )
    doc = load_yaml(tmp_path / "m.yaml")
    assert (doc["mode"], doc["occupied_thresh"], doc["free_thresh"]) == (mode, 0.7, 0.2)


def test_scale_png_has_alpha_and_unknown_is_transparent(tmp_path: Path) -> None:
    image, _ = write_map(tmp_path / "m.png", omap([[0.0, NAN], [1.0, 0.5]]), mode="scale")
    with Image.open(image) as img:
        assert img.mode == "LA"
        px = np.asarray(img)
    # top image row is map row 1: [1.0, 0.5]; bottom is map row 0: [0.0, unknown]
    assert px[..., 1].tolist() == [[255, 255], [255, 0]]
    assert px[..., 0][0].tolist() == [0, 128] and px[1, 0, 0] == 255


@pytest.mark.parametrize("mode", ["trinary", "raw"])
def test_trinary_and_raw_pngs_have_no_alpha(tmp_path: Path, mode: str) -> None:
    image, _ = write_map(tmp_path / "m.png", omap([[0.0, NAN]]), mode=mode)
    with Image.open(image) as img:
        assert img.mode == "L"
        assert np.asarray(img).tolist() == ([[254, 205]] if mode == "trinary" else [[0, 255]])


def test_force_overwrites_both_files(tmp_path: Path) -> None:
    write_map(tmp_path / "m.pgm", omap([[0.0, 0.0]]))
    write_map(tmp_path / "m.pgm", omap([[1.0]], x0=4.0), force=True)
    assert (tmp_path / "m.pgm").read_bytes() == b"P5\n1 1\n255\n\x00"
    assert load_yaml(tmp_path / "m.yaml")["origin"] == [4.0, 0.0, 0.0]


def test_yaml_target_that_is_a_directory_leaves_no_image(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").mkdir()
    with pytest.raises(UsageError, match="is a directory"):
        write_map(tmp_path / "m.pgm", omap([[0.0]]), force=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.yaml"]


def test_failed_write_leaves_no_image_and_no_temporary_files(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # skip the early check, so the failure happens while the files are written: the image is
    # complete by then, and must still not appear
    monkeypatch.setattr(map_image, "check_map_outputs", lambda *args: None)
    (tmp_path / "m.yaml").mkdir()
    with pytest.raises(GridmapError, match=r"m\.yaml: cannot write the map"):
        write_map(tmp_path / "m.pgm", omap([[0.0]]), force=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.yaml"]


def test_failed_write_keeps_the_previous_image(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    write_map(tmp_path / "m.pgm", omap([[0.0]]))
    before = (tmp_path / "m.pgm").read_bytes()
    (tmp_path / "m.yaml").unlink()
    (tmp_path / "m.yaml").mkdir()
    monkeypatch.setattr(map_image, "check_map_outputs", lambda *args: None)
    with pytest.raises(GridmapError):
        write_map(tmp_path / "m.pgm", omap([[1.0, 1.0]]), force=True)
    assert (tmp_path / "m.pgm").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.pgm", "m.yaml"]


def test_file_names_that_need_quoting_survive(tmp_path: Path) -> None:
    name = "it's: #1.png"
    write_map(tmp_path / name, omap([[0.0]]))
    assert load_yaml(tmp_path / "it's: #1.yaml")["image"] == name


def test_shape_mismatch_is_refused(tmp_path: Path) -> None:
    bad = OccupancyMap(GridSpec(0.0, 0.0, 0.1, 3, 2), np.zeros((3, 2)))
    with pytest.raises(ValueError, match="shape"):
        write_map(tmp_path / "m.pgm", bad)
    assert list(tmp_path.iterdir()) == []
