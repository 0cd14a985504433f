"""build takes map_saver_cli's habits (-f BASENAME, --fmt pgm|png|bmp, --occ/--free in 0..1),
and points a ROS user's habits (--mode trinary, a folder of logs) to gridmap's own words."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.helpers import names, run

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "corridor_loop.csv"
ARIA = SAMPLE.with_suffix(".2d")


def build(*args: str) -> tuple[int, str]:
    code, _, err = run("build", str(SAMPLE), "-q", *args)
    return code, err


def test_f_basename_writes_a_pgm_and_yaml_like_o(tmp_path: Path) -> None:
    # folders a/ and b/ do not exist yet: -o and -f alike make them
    assert build("-o", str(tmp_path / "a" / "map.pgm")) == (0, "")
    assert build("-f", str(tmp_path / "b" / "map")) == (0, "")
    assert names(tmp_path / "b") == {"map.pgm", "map.yaml"}
    for name in ("map.pgm", "map.yaml"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


@pytest.mark.parametrize("fmt", ["png", "bmp"])
def test_fmt_picks_the_image_format_with_the_same_cells(tmp_path: Path, fmt: str) -> None:
    assert build("-f", str(tmp_path / "map")) == (0, "")
    assert build("-f", str(tmp_path / "other"), "--fmt", fmt) == (0, "")
    image = tmp_path / f"other.{fmt}"
    assert Image.open(image).format == fmt.upper()
    grey = np.asarray(Image.open(image).convert("L"))
    assert np.array_equal(grey, np.asarray(Image.open(tmp_path / "map.pgm")))
    assert f"image: other.{fmt}\n" in (tmp_path / "other.yaml").read_text()


def test_occ_is_occupied(tmp_path: Path) -> None:
    assert build("-o", str(tmp_path / "a.pgm"), "--occ", "0.8", "--free", "0.3")[0] == 0
    assert build("-o", str(tmp_path / "b.pgm"), "--occupied", "0.8", "--free", "0.3")[0] == 0
    assert build("-o", str(tmp_path / "c.pgm"))[0] == 0
    a, b, c = ((tmp_path / f"{n}.pgm").read_bytes() for n in "abc")
    assert a == b != c


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((), "give the map to write: -o FILE or -f BASENAME (one of them)"),
        (("-o", "{t}/m.pgm", "-f", "{t}/m"), "give the map to write: -o FILE or -f BASENAME"),
        (("-o", "{t}/m.png", "--fmt", "pgm"), "--fmt pgm does not match -o {t}/m.png"),
        (("-f", "{t}/m", "--fmt", "bmp", "--map-mode", "scale"), "scale maps need a PNG"),
    ],
)
def test_bad_map_saver_flags_are_usage_errors(
    tmp_path: Path, args: tuple[str, ...], message: str
) -> None:
    code, err = build(*(a.format(t=tmp_path) for a in args))
    assert code == 2
    assert err.startswith("Error: ") and err.count("\n") == 1
    assert message.format(t=tmp_path) in err
    assert names(tmp_path) == set()


def test_a_missing_log_is_reported_before_an_existing_output(tmp_path: Path) -> None:
    existing = tmp_path / "map.pgm"
    existing.write_bytes(b"keep")
    code, _, err = run("build", str(tmp_path / "missing.csv"), "-o", str(existing))
    assert (code, err.strip()) == (1, f"Error: {tmp_path / 'missing.csv'}: no such file")
    assert existing.read_bytes() == b"keep"


@pytest.mark.parametrize("value", ["trinary", "scale", "raw"])
def test_a_map_mode_given_to_mode_points_to_map_mode(tmp_path: Path, value: str) -> None:
    code, err = build("-o", str(tmp_path / "map.pgm"), "--mode", value)
    assert (code, err) == (
        2,
        f"Error: Invalid value for '--mode': '{value}' is a map mode (how the image stores "
        f"occupancy): give --map-mode {value}; --mode is the mapping algorithm, one of "
        "'standard', 'error-aware'\n",
    )
    assert names(tmp_path) == set()


def test_another_bad_mode_keeps_clicks_message(tmp_path: Path) -> None:
    code, err = build("-o", str(tmp_path / "map.pgm"), "--mode", "fast")
    assert (code, err) == (
        2,
        "Error: Invalid value for '--mode': 'fast' is not one of 'standard', 'error-aware'.\n",
    )
    assert names(tmp_path) == set()


@pytest.mark.parametrize("fmt", ["pgm", "png", "bmp"])
def test_f_with_an_image_extension_picks_the_format_once(tmp_path: Path, fmt: str) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    assert build("-f", str(tmp_path / "a" / f"map.{fmt}")) == (0, "")
    assert names(tmp_path / "a") == {f"map.{fmt}", "map.yaml"}
    assert build("-f", str(tmp_path / "b" / f"map.{fmt}"), "--fmt", fmt) == (0, "")
    assert build("-f", str(tmp_path / "b" / "other"), "--fmt", fmt) == (0, "")
    pillow_name = {"pgm": "PPM", "png": "PNG", "bmp": "BMP"}[fmt]
    assert Image.open(tmp_path / "a" / f"map.{fmt}").format == pillow_name
    other = (tmp_path / "b" / f"other.{fmt}").read_bytes()
    assert other == (tmp_path / "a" / f"map.{fmt}").read_bytes()
    assert f"image: map.{fmt}\n" in (tmp_path / "a" / "map.yaml").read_text()
    for name in (f"map.{fmt}", "map.yaml"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


def test_f_with_another_extension_still_gets_one_added(tmp_path: Path) -> None:
    assert build("-f", str(tmp_path / "run.2024")) == (0, "")
    assert names(tmp_path) == {"run.2024.pgm", "run.2024.yaml"}


def test_f_extension_and_a_different_fmt_are_a_usage_error(tmp_path: Path) -> None:
    code, err = build("-f", str(tmp_path / "map.pgm"), "--fmt", "png")
    assert (code, err) == (2, f"Error: --fmt png does not match -f {tmp_path / 'map.pgm'}\n")
    assert names(tmp_path) == set()


def test_a_folder_of_text_logs_points_to_batch(tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    for log in (SAMPLE, ARIA):
        (logs / log.name).write_bytes(log.read_bytes())
    code, _, err = run("build", str(logs), "-o", str(tmp_path / "map.pgm"))
    assert (code, err) == (
        1,
        f"Error: {logs}: a directory, but not a rosbag2 folder (no metadata.yaml in it); "
        f"gridmap batch {logs} -o OUTDIR maps each log in a folder\n",
    )
    assert names(tmp_path) == {"logs"}
    assert names(logs) == {SAMPLE.name, ARIA.name}


def test_several_text_logs_point_to_batch_and_fuse(tmp_path: Path) -> None:
    code, _, err = run("build", str(SAMPLE), str(ARIA), "-o", str(tmp_path / "map.pgm"))
    assert (code, err) == (
        2,
        f"Error: {SAMPLE}: several logs are read as one only when all are ROS recordings "
        "(MCAP, bag, rosbag2 folder); this is a csv log; gridmap batch maps each log on its own, "
        "and build --fuse maps several runs through one place into one map\n",
    )
    assert names(tmp_path) == set()


def nav2_static_layer(occupancy: np.ndarray) -> np.ndarray:
    """Costs Nav2's static layer gives a loaded map with its defaults (``trinary_costmap: true``,
    ``lethal_cost_threshold: 100``, ``track_unknown_space: true``): 254 lethal, 255 no
    information, 0 free. AMCL likewise reads only 100 as occupied and only 0 as free."""
    return np.where(occupancy == -1, 255, np.where(occupancy >= 100, 254, 0))


def test_raw_and_scale_walls_are_lethal_where_trinary_ones_are(tmp_path: Path) -> None:
    """The cells a built map calls occupied load as 100 in every mode and on every loader, so
    Nav2 with its default costmap parameters, AMCL and ROS 1 map_server see the same walls."""
    from gridmap_cli.mapping.mapfile import LOADER_FLAVOURS, load_map

    loaded = {}
    for mode, suffix in (("trinary", "pgm"), ("raw", "pgm"), ("scale", "png")):
        code, err = build("-o", str(tmp_path / f"{mode}.{suffix}"), "--map-mode", mode)
        assert code == 0, err
        for flavour in LOADER_FLAVOURS:
            loaded[mode, flavour] = load_map(tmp_path / f"{mode}.yaml", flavour).occupancy
    for flavour in LOADER_FLAVOURS:
        walls = loaded["trinary", flavour] == 100
        assert walls.sum() > 100  # the corridor's walls
        for mode in ("raw", "scale"):
            occupancy = loaded[mode, flavour]
            assert np.array_equal(nav2_static_layer(occupancy) == 254, walls), (mode, flavour)
            # free loads as free (Nav2's scale mode also rounds cells just above the free
            # threshold to 0: round(100 ratio))
            assert (occupancy[loaded["trinary", flavour] == 0] == 0).all(), (mode, flavour)
