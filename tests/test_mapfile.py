"""The map loader: each flavour reads pixels as its real loader does, and bad files are named."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from PIL import Image

from gridmap_cli.errors import InputFileError, UsageError
from gridmap_cli.mapping.grid import GridSpec, OccupancyMap
from gridmap_cli.mapping.mapfile import LOADER_FLAVOURS, LoadedMap, load_map
from gridmap_cli.writers.map_image import write_map

NAN = math.nan
STRICT = ("ros1", "nav2-humble")


def yaml_text(
    image: str = "m.pgm",
    *,
    mode: str | None = None,
    resolution: str = "0.1",
    origin: str = "[0.0, 0.0, 0.0]",
    negate: str = "0",
    occupied: str = "0.65",
    free: str = "0.196",
) -> str:
    lines = [f"image: {image}"]
    if mode is not None:
        lines.append(f"mode: {mode}")
    lines += [
        f"resolution: {resolution}",
        f"origin: {origin}",
        f"negate: {negate}",
        f"occupied_thresh: {occupied}",
        f"free_thresh: {free}",
    ]
    return "\n".join(lines) + "\n"


def write_image(path: Path, pixels: npt.NDArray[np.uint8]) -> Path:
    """Save pixels (top row first) with Pillow: (H, W) grey, (H, W, 2) grey+alpha, (H, W, 3|4)."""
    Image.fromarray(np.ascontiguousarray(pixels, dtype=np.uint8)).save(path)
    return path


def write_case(
    folder: Path, pixels: npt.NDArray[np.uint8], suffix: str = ".pgm", **yaml_fields: str
) -> Path:
    write_image(folder / f"m{suffix}", pixels)
    meta = folder / "m.yaml"
    meta.write_text(yaml_text(f"m{suffix}", **yaml_fields), encoding="utf-8")
    return meta


def every_grey() -> npt.NDArray[np.uint8]:
    """16 x 16 image holding every grey value once: pixel (row, col) = 16 row + col."""
    return np.arange(256, dtype=np.uint8).reshape(16, 16)


# --- reference rules, written from docs/map-format.md one pixel at a time ------------------------


def ref_pixel(p: float, mode: str, occupied: float, free: float) -> tuple[int, int]:
    """(grey, alpha) the writer should store for probability p; grey -1 = unspecified."""
    if math.isnan(p):
        return {"trinary": (205, 255), "scale": (-1, 0), "raw": (255, 255)}[mode]
    if mode == "trinary":
        return (0 if p >= occupied else 254 if p <= free else 205), 255
    if mode == "scale":
        # a cell the map calls occupied or free: a grey every loader reads as such
        grey = round(255 * (1 - p))
        if p >= occupied:
            grey = min(grey, max(g for g in range(256) if (255 - g) / 255 > occupied))
        if p <= free:
            grey = max(grey, min(g for g in range(256) if (255 - g) / 255 < free))
        return grey, 255
    return (100 if p >= occupied else 0 if p <= free else min(99, max(1, round(100 * p)))), 255


def ref_load(grey: int, alpha: int, mode: str, flavour: str, occupied: float, free: float) -> int:
    """Occupancy one loader gives an opaque grey pixel (or a transparent one in scale mode)."""
    if mode == "raw":
        return grey if grey <= 100 else -1
    p = (255 - grey) / 255
    if flavour == "nav2-jazzy":
        is_occupied, is_free = p >= occupied, p <= free
    else:
        is_occupied, is_free = p > occupied, p < free
    if mode == "scale" and alpha < 255 and flavour != "ros1":
        return -1  # Nav2: anything not fully opaque is unknown
    if is_occupied:
        return 100
    if is_free:
        return 0
    if mode == "trinary":
        return -1
    ratio = (p - free) / (occupied - free)
    if flavour == "ros1":
        return -1 if alpha == 0 else int(1 + 98 * ratio)
    if flavour == "nav2-humble":
        return round(100 * ratio)  # rint: halves to even, as Python's round
    return math.floor(100 * ratio + 0.5)  # Eigen round: halves away from zero


# --- the cases of docs/map-format.md -------------------------------------------------------------


def test_black_white_map_round_trip_keeps_cells_and_origin(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    prob = (rng.random((10, 10)) < 0.4).astype(np.float64)
    prob[0, :] = [1.0] * 3 + [0.0] * 7  # a bottom row that is not symmetric
    spec = GridSpec(2.0, 3.0, 0.1, 10, 10)
    image, meta = write_map(tmp_path / "bw.pgm", OccupancyMap(spec, prob))

    # the bottom image row is map row 0
    pixels = np.asarray(Image.open(image))
    assert pixels[-1].tolist() == [0] * 3 + [254] * 7
    for flavour in LOADER_FLAVOURS:
        loaded = load_map(meta, flavour)
        assert loaded.spec == spec
        assert loaded.occupancy.dtype == np.int8 and loaded.occupancy.shape == (10, 10)
        assert np.array_equal(loaded.occupancy, np.where(prob == 1.0, 100, 0))
        assert loaded.origin_yaw_rad == 0.0


def test_a_yaw_in_the_origin_loads_and_x_y_are_kept(tmp_path: Path) -> None:
    img = np.full((10, 10), 254, dtype=np.uint8)
    img[-1, 0] = 0  # lower-left pixel occupied
    meta = write_case(tmp_path, img, origin="[2.0, 3.0, 1.0]")
    loaded = load_map(meta)
    assert (loaded.spec.origin_x_m, loaded.spec.origin_y_m, loaded.origin_yaw_rad) == (
        2.0,
        3.0,
        1.0,
    )
    assert loaded.occupancy[0, 0] == 100 and loaded.occupancy.sum() == 100
    # cell (0, 0) is the lower-left one, its centre half a cell from the origin
    col, row = loaded.spec.world_to_cell(np.array([2.05]), np.array([3.05]))
    assert loaded.occupancy[row[0], col[0]] == 100


@pytest.mark.parametrize("flavour", LOADER_FLAVOURS)
def test_every_grey_trinary_90_occupied_26_free_140_unknown(tmp_path: Path, flavour: str) -> None:
    meta = write_case(tmp_path, every_grey(), mode="trinary", occupied="0.65", free="0.1")
    occ = load_map(meta, flavour).occupancy
    assert (np.count_nonzero(occ == 100), np.count_nonzero(occ == 0)) == (90, 26)
    assert np.count_nonzero(occ == -1) == 140
    # map row 0 is the image's bottom row, greys 240..255: all free
    assert occ[0].tolist() == [0] * 16
    assert occ[-1, 0] == 100  # grey 0, top-left of the image


@pytest.mark.parametrize("flavour", LOADER_FLAVOURS)
def test_every_grey_scale_90_occupied_26_free_140_between(tmp_path: Path, flavour: str) -> None:
    meta = write_case(tmp_path, every_grey(), mode="scale", occupied="0.65", free="0.1")
    occ = load_map(meta, flavour).occupancy[::-1].ravel()  # back to grey order 0..255
    p = (255 - np.arange(256)) / 255
    occupied, free = p > 0.65, p < 0.1  # no grey lies on a threshold here
    between = ~(occupied | free)
    assert (occupied.sum(), free.sum(), between.sum()) == (90, 26, 140)
    assert np.all(occ[occupied] == 100) and np.all(occ[free] == 0)
    low, high = (1, 99) if flavour == "ros1" else (0, 100)
    assert np.all((occ[between] >= low) & (occ[between] <= high))
    # darker is never less occupied
    assert np.all(np.diff(occ[between].astype(int)) <= 0)
    assert len(set(occ[between].tolist())) > 90


@pytest.mark.parametrize("flavour", LOADER_FLAVOURS)
def test_every_grey_raw_gives_each_occupancy_once(tmp_path: Path, flavour: str) -> None:
    meta = write_case(tmp_path, every_grey(), mode="raw")
    occ = load_map(meta, flavour).occupancy
    values, counts = np.unique(occ[occ >= 0], return_counts=True)
    assert values.tolist() == list(range(101)) and set(counts.tolist()) == {1}
    assert np.count_nonzero(occ == -1) == 155


@pytest.mark.parametrize("flavour", LOADER_FLAVOURS)
@pytest.mark.parametrize("mode", ["trinary", "scale"])
def test_negate_inverts(tmp_path: Path, flavour: str, mode: str) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    plain = write_case(tmp_path / "a", 255 - every_grey(), mode=mode, occupied="0.65", free="0.1")
    negated = write_case(
        tmp_path / "b", every_grey(), mode=mode, negate="1", occupied="0.65", free="0.1"
    )
    a, b = load_map(plain, flavour), load_map(negated, flavour)
    assert b.negate and not a.negate
    assert np.array_equal(a.occupancy, b.occupancy)
    assert np.count_nonzero(b.occupancy == 100) == 90  # white is occupied now
    assert b.occupancy[-1, 0] == 0  # grey 0, black, is free


def test_negate_in_raw_mode_only_matters_to_ros1(tmp_path: Path) -> None:
    meta = write_case(tmp_path, np.array([[0, 30, 250]], dtype=np.uint8), mode="raw", negate="1")
    assert load_map(meta, "ros1").occupancy.tolist() == [[-1, -1, 5]]
    assert load_map(meta, "nav2-humble").occupancy.tolist() == [[0, 30, -1]]
    assert load_map(meta, "nav2-jazzy").occupancy.tolist() == [[0, 30, -1]]


@pytest.mark.parametrize(("occupied", "free"), [("0.5", "0.5"), ("0.25", "0.65")])
def test_thresholds_with_occupied_not_above_free_are_refused(
    tmp_path: Path, occupied: str, free: str
) -> None:
    meta = write_case(tmp_path, every_grey(), occupied=occupied, free=free)
    with pytest.raises(InputFileError) as err:
        load_map(meta)
    assert str(err.value) == (
        f"{meta}:5: occupied_thresh ({float(occupied)}) must be greater than "
        f"free_thresh ({float(free)})"
    )


def test_missing_image_is_an_error_naming_the_path(tmp_path: Path) -> None:
    meta = tmp_path / "m.yaml"
    meta.write_text(yaml_text("maps/gone.pgm"), encoding="utf-8")
    with pytest.raises(InputFileError) as err:
        load_map(meta)
    assert str(err.value) == f"{meta}:1: image {tmp_path / 'maps' / 'gone.pgm'} does not exist"


# --- round trips: what the writer stores is what each loader is predicted to read ----------------


@pytest.mark.parametrize(
    ("mode", "suffix", "occupied", "free"),
    [
        ("trinary", ".pgm", 0.65, 0.25),
        ("trinary", ".png", 0.7, 0.2),
        ("scale", ".png", 0.65, 0.25),
        ("scale", ".png", 0.7, 0.2),  # grey 204 (p = 0.2) sits on the free threshold
        ("raw", ".pgm", 0.65, 0.25),
        ("raw", ".png", 0.65, 0.25),
    ],
)
def test_round_trip_gives_the_predicted_occupancy(
    tmp_path: Path, mode: str, suffix: str, occupied: float, free: float
) -> None:
    rng = np.random.default_rng(11)
    prob = rng.random((9, 12))
    prob[rng.random(prob.shape) < 0.2] = NAN
    prob[0, :6] = [0.0, 1.0, free, occupied, 0.2, 0.5]  # exact thresholds and halves
    spec = GridSpec(-1.25, 0.5, 0.05, 12, 9)
    image, meta = write_map(
        tmp_path / f"m{suffix}",
        OccupancyMap(spec, prob),
        mode=mode,
        occupied_thresh=occupied,
        free_thresh=free,
    )
    with Image.open(image) as img:
        stored = np.asarray(img)[::-1]  # map row order
    grey = stored[..., 0] if stored.ndim == 3 else stored
    alpha = stored[..., 1] if stored.ndim == 3 else np.full(grey.shape, 255)
    yaml_occ, yaml_free = (0.65, 0.196) if mode == "trinary" else (occupied, free)

    at_free_thresh: dict[str, int] = {}
    for flavour in LOADER_FLAVOURS:
        loaded = load_map(meta, flavour)
        assert loaded.spec == spec and loaded.mode == mode
        for (r, c), p in np.ndenumerate(prob):
            want_grey, want_alpha = ref_pixel(float(p), mode, occupied, free)
            if want_grey >= 0:
                assert grey[r, c] == want_grey, (r, c, p)
            assert alpha[r, c] == want_alpha
            want = ref_load(int(grey[r, c]), int(alpha[r, c]), mode, flavour, yaml_occ, yaml_free)
            assert loaded.occupancy[r, c] == want, (flavour, r, c, p)
            if math.isnan(p):
                assert want == -1  # never observed loads as unknown on every loader
        at_free_thresh[flavour] = int(loaded.occupancy[0, 4])
    if mode == "scale" and free == 0.2:
        # p = 0.2 would be grey 204, p = 0.2 exactly: between the thresholds for ROS 1
        # (1 + 98 * 0), free for Jazzy; a cell the map calls free is stored as 205 instead,
        # free on every loader
        assert grey[0, 4] == 205
        assert set(at_free_thresh.values()) == {0}
    if mode != "trinary":
        # every cell the map calls occupied loads as 100, free as 0, on every loader
        for flavour in LOADER_FLAVOURS:
            loaded = load_map(meta, flavour).occupancy
            assert (loaded[prob >= occupied] == 100).all() and (loaded[prob <= free] == 0).all()


def test_grey_204_with_free_0_2_is_unknown_strictly_and_free_inclusively(tmp_path: Path) -> None:
    meta = write_case(tmp_path, np.array([[204]], dtype=np.uint8), occupied="0.65", free="0.2")
    assert [load_map(meta, f).occupancy[0, 0] for f in LOADER_FLAVOURS] == [-1, -1, 0]


# --- alpha and colour ----------------------------------------------------------------------------


def test_trinary_alpha_is_averaged_in_by_ros1_and_humble_but_unknown_on_jazzy(
    tmp_path: Path,
) -> None:
    # (grey, alpha): opaque white; transparent white -> (3*254 + 0)/4 = 190.5, p = 0.25;
    # transparent black -> 0, occupied
    pixels = np.array([[[254, 255], [254, 0], [0, 0]]], dtype=np.uint8)
    meta = write_case(tmp_path, pixels, suffix=".png", mode="trinary")
    for flavour in STRICT:
        assert load_map(meta, flavour).occupancy.tolist() == [[0, -1, 100]]
    assert load_map(meta, "nav2-jazzy").occupancy.tolist() == [[0, -1, -1]]


def test_scale_alpha_per_flavour(tmp_path: Path) -> None:
    # transparent black, half-transparent mid grey, transparent mid grey, opaque mid grey
    pixels = np.array([[[0, 0], [128, 128], [128, 0], [128, 255]]], dtype=np.uint8)
    meta = write_case(tmp_path, pixels, suffix=".png", mode="scale", occupied="0.65", free="0.25")
    ratio = ((255 - 128) / 255 - 0.25) / 0.4
    ros1_mid = int(1 + 98 * ratio)
    nav2_mid = round(100 * ratio)
    # ROS 1 looks at alpha (== 0 only) for in-between pixels alone
    assert load_map(meta, "ros1").occupancy.tolist() == [[100, ros1_mid, -1, ros1_mid]]
    for flavour in ("nav2-humble", "nav2-jazzy"):
        assert load_map(meta, flavour).occupancy.tolist() == [[-1, -1, -1, nav2_mid]]


def test_colour_pixels_average_their_channels(tmp_path: Path) -> None:
    # (0, 0, 30) averages to 10: occupied; (250, 255, 254) to 253: free; (200, 200, 0) to 133.3:
    # between, and blue 0 is what ROS 1 takes for alpha in an RGB image
    pixels = np.array([[[0, 0, 30], [250, 255, 254], [200, 200, 0]]], dtype=np.uint8)
    meta = write_case(tmp_path, pixels, suffix=".png", mode="scale", occupied="0.65", free="0.25")
    assert load_map(meta, "ros1").occupancy.tolist() == [[100, 0, -1]]
    mid = round(100 * ((255 - 133) / 255 - 0.25) / 0.4)
    assert load_map(meta, "nav2-jazzy").occupancy.tolist() == [[100, 0, mid]]


# --- the YAML: accepted variants and errors with file and line -----------------------------------


def test_image_path_may_be_absolute_and_negate_a_boolean(tmp_path: Path) -> None:
    (tmp_path / "img").mkdir()
    image = write_image(tmp_path / "img" / "x.png", np.array([[0, 254]], dtype=np.uint8))
    meta = tmp_path / "m.yaml"
    meta.write_text(yaml_text(str(image), negate="false", resolution="5e-2"), encoding="utf-8")
    loaded = load_map(meta)
    assert loaded.image_path == image
    assert loaded.spec.resolution_m == 0.05  # yaml-cpp reads 5e-2 as a number, so do we
    assert loaded.occupancy.tolist() == [[100, 0]] and loaded.negate is False


def test_relative_image_is_found_from_any_working_directory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "maps").mkdir()
    write_case(tmp_path / "maps", np.array([[0]], dtype=np.uint8))
    monkeypatch.chdir(tmp_path)
    assert load_map(Path("maps/m.yaml")).occupancy.tolist() == [[100]]


def test_mode_defaults_to_trinary(tmp_path: Path) -> None:
    meta = write_case(tmp_path, np.array([[100]], dtype=np.uint8))
    loaded = load_map(meta)
    assert loaded.mode == "trinary" and loaded.occupancy.tolist() == [[-1]]  # p = 0.61


@pytest.mark.parametrize(
    ("fields", "expected"),
    [
        ({"resolution": "0"}, ":2: resolution must be a positive number, got 0"),
        ({"resolution": "-0.05"}, ":2: resolution must be a positive number, got -0.05"),
        ({"resolution": ".nan"}, ":2: resolution must be a positive number, got nan"),
        ({"resolution": "fine"}, ":2: resolution must be a positive number, got 'fine'"),
        (
            {"origin": "[1.0, 2.0]"},
            ":3: origin must be three finite numbers [x, y, yaw], got [1.0, 2.0]",
        ),
        ({"origin": "[1.0, .inf, 0]"}, ":3: origin must be three finite numbers"),
        ({"origin": "[a, b, c]"}, ":3: origin must be three finite numbers"),
        ({"origin": "0.0"}, ":3: origin must be three finite numbers"),
        ({"negate": "maybe"}, ":4: negate must be 0 or 1, got 'maybe'"),
        ({"occupied": "high"}, ":5: occupied_thresh must be a number, got 'high'"),
        ({"free": ".nan"}, ":6: free_thresh must be a number, got nan"),
        ({"mode": "ternary"}, ":2: unknown mode 'ternary' (known: trinary, scale, raw)"),
    ],
)
def test_bad_values_name_the_file_and_line(
    tmp_path: Path, fields: dict[str, str], expected: str
) -> None:
    meta = write_case(tmp_path, np.zeros((2, 2), dtype=np.uint8), **fields)
    with pytest.raises(InputFileError) as err:
        load_map(meta)
    assert str(err.value).startswith(f"{meta}{expected}")


@pytest.mark.parametrize(
    "key", ["image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh"]
)
def test_missing_keys_are_named(tmp_path: Path, key: str) -> None:
    write_image(tmp_path / "m.pgm", np.zeros((1, 1), dtype=np.uint8))
    text = "".join(
        line + "\n" for line in yaml_text().splitlines() if not line.startswith(f"{key}:")
    )
    meta = tmp_path / "m.yaml"
    meta.write_text(text, encoding="utf-8")
    with pytest.raises(InputFileError) as err:
        load_map(meta)
    assert str(err.value) == f"{meta}: missing key '{key}'"


def test_missing_yaml(tmp_path: Path) -> None:
    with pytest.raises(InputFileError) as err:
        load_map(tmp_path / "none.yaml")
    assert str(err.value) == f"{tmp_path / 'none.yaml'}: no such file"


def test_yaml_that_is_a_directory(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="is a directory"):
        load_map(tmp_path)


@pytest.mark.parametrize("text", ["", "- image: m.pgm\n", "just words\n"])
def test_yaml_that_is_not_a_mapping(tmp_path: Path, text: str) -> None:
    meta = tmp_path / "m.yaml"
    meta.write_text(text, encoding="utf-8")
    with pytest.raises(InputFileError) as err:
        load_map(meta)
    assert str(err.value) == f"{meta}: not a map YAML: expected a mapping of keys to values"


def test_broken_yaml_names_the_line(tmp_path: Path) -> None:
    meta = tmp_path / "m.yaml"
    meta.write_text(
        "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0\nnegate: 0\n", encoding="utf-8"
    )
    with pytest.raises(InputFileError) as err:
        load_map(meta)
    assert str(err.value).startswith(f"{meta}:4: not valid YAML")


def test_unreadable_image_names_the_image(tmp_path: Path) -> None:
    (tmp_path / "m.pgm").write_bytes(b"this is not an image")
    meta = tmp_path / "m.yaml"
    meta.write_text(yaml_text(), encoding="utf-8")
    with pytest.raises(InputFileError) as err:
        load_map(meta)
    assert str(err.value).startswith(f"{tmp_path / 'm.pgm'}: cannot read the image")


def test_sixteen_bit_images_are_refused(tmp_path: Path) -> None:
    Image.fromarray(np.zeros((2, 2), dtype=np.uint16)).save(tmp_path / "m.png")
    meta = tmp_path / "m.yaml"
    meta.write_text(yaml_text("m.png"), encoding="utf-8")
    with pytest.raises(InputFileError, match=r"m\.png: unsupported image mode"):
        load_map(meta)


def test_image_that_is_a_directory(tmp_path: Path) -> None:
    (tmp_path / "m.pgm").mkdir()
    meta = tmp_path / "m.yaml"
    meta.write_text(yaml_text(), encoding="utf-8")
    with pytest.raises(InputFileError, match=r":1: image .*m\.pgm is not a file"):
        load_map(meta)


def test_unknown_flavour_is_a_usage_error(tmp_path: Path) -> None:
    meta = write_case(tmp_path, np.zeros((1, 1), dtype=np.uint8))
    with pytest.raises(UsageError, match="nav2-iron"):
        load_map(meta, "nav2-iron")


# --- LoadedMap helpers ---------------------------------------------------------------------------


def test_occupied_mask_and_probability() -> None:
    occ = np.array([[-1, 0, 49], [50, 99, 100]], dtype=np.int8)
    loaded = LoadedMap(
        GridSpec(0.0, 0.0, 1.0, 3, 2), occ, Path("m.png"), "scale", False, 0.65, 0.25
    )
    assert loaded.occupied_mask().tolist() == [[False, False, False], [True, True, True]]
    assert loaded.occupied_mask(100).tolist() == [[False, False, False], [False, False, True]]
    prob = loaded.probability()
    assert np.isnan(prob[0, 0])
    assert prob[0, 1:].tolist() == [0.0, 0.49] and prob[1].tolist() == [0.5, 0.99, 1.0]
