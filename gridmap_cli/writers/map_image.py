"""Writer for map_server maps: an image (PGM or PNG) plus the YAML that describes it.

The files follow ``docs/map-format.md`` so that ROS 1 ``map_server``, Nav2's ``nav2_map_server``
(Humble and Jazzy) load them alike; MRPT 2.5's ROS map loader reads trinary and scale maps, not
raw ones:

- ``trinary``: grey 0 occupied, 254 free, 205 unknown, classified from probabilities with the
  given thresholds (as ``map_saver --occ 65 --free 25`` does); the YAML always says
  ``occupied_thresh: 0.65`` / ``free_thresh: 0.196``, which separate those three grey values on
  every loader whatever thresholds classified the cells.
- ``scale``: grey = 255 (1 - p) with an alpha channel (PNG only); unknown cells transparent.
- ``raw``: grey = 100 p (the occupancy percentage itself), unknown 255.

In ``scale`` and ``raw`` a cell the map calls occupied (p >= the occupied threshold) loads as
occupied (100) and one it calls free (p <= the free threshold) as free (0) on every loader:
Nav2's costmap with its defaults (``trinary_costmap``, ``lethal_cost_threshold: 100``) and
AMCL take only 100 as a wall and only 0 as free, and the map's probabilities are clamped below
1 (``DEFAULT_CLAMP_P``), so a plain 100 p would never reach 100. A raw occupied cell is written
100, a free one 0, the others round(100 p) kept within 1..99; a scale cell's grey is moved, where
rounding would leave it on the wrong side of a loading threshold, to the nearest grey that is on
the right side under the strict comparisons of ROS 1 and Nav2 Humble.

The image is written top row first (image row 0 is map row height-1); both files are written
together through :func:`~gridmap_cli.atomic.atomic_outputs`, so a failure leaves neither behind.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt
import yaml
from PIL import Image

from gridmap_cli.atomic import atomic_outputs
from gridmap_cli.errors import GridmapError, UsageError
from gridmap_cli.mapping.grid import GridSpec, OccupancyMap
from gridmap_cli.writers import check_output
from gridmap_cli.yamlfile import format_float

MAP_MODES = ("trinary", "scale", "raw")
IMAGE_SUFFIXES = (".pgm", ".png", ".bmp")
#: The image formats as map_saver_cli's ``--fmt`` names them.
IMAGE_FORMATS = tuple(s.lstrip(".") for s in IMAGE_SUFFIXES)

#: Grey values of the map_server savers in trinary mode.
OCCUPIED_GREY = 0
FREE_GREY = 254
UNKNOWN_GREY = 205
#: Raw mode's grey for a cell never observed: outside 0..100, so every loader reads it as unknown.
RAW_UNKNOWN_GREY = 255

#: Loading thresholds written in the YAML of every trinary map (see the module docstring): 205 has
#: p = 50/255 = 0.19608 > 0.196, so it stays unknown, while 254 (p = 0.0039) is free and 0
#: (p = 1) occupied, with strict or inclusive comparisons alike.
TRINARY_YAML_OCCUPIED_THRESH = 0.65
TRINARY_YAML_FREE_THRESH = 0.196

#: Files written with a map in one atomic block (:func:`write_map`'s ``also``): their targets,
#: and a function writing them to the temporary paths it is given, in the same order.
ExtraOutput = tuple[tuple[Path, ...], Callable[[list[Path]], None]]

# An image name that YAML reads back as the same plain string without any quoting.
_PLAIN_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*")


def map_output_paths(image_path: Path) -> tuple[Path, Path]:
    """The image path and the YAML beside it (same folder, same stem, ``.yaml``).

    Raises :class:`UsageError` when the suffix is not one of :data:`IMAGE_SUFFIXES` (compared
    without regard to case) or when the file name cannot be written as a YAML string.
    """
    image_path = Path(image_path)
    if image_path.suffix.lower() not in IMAGE_SUFFIXES:
        raise UsageError(
            f"{image_path}: a map image must end in {' or '.join(IMAGE_SUFFIXES)}, "
            f"not '{image_path.suffix}'"
        )
    _yaml_string(image_path.name)  # refuse names the YAML could not hold before any work
    return image_path, image_path.with_suffix(".yaml")


def check_map_outputs(image_path: Path, mode: str, force: bool) -> None:
    """Check that a map can be written to ``image_path`` in ``mode``; call before any work.

    Raises :class:`UsageError` for an unknown mode, ``scale`` with a PGM (which has no alpha
    channel to mark unknown cells), an unsupported suffix or an output that is a directory, and
    :class:`OutputExistsError` when the image or its YAML exists and ``force`` is false.
    """
    if mode not in MAP_MODES:
        raise UsageError(f"unknown map mode '{mode}' (known: {', '.join(MAP_MODES)})")
    image, yaml_path = map_output_paths(image_path)
    if mode == "scale" and image.suffix.lower() != ".png":
        raise UsageError(
            f"{image}: scale maps need a PNG (unknown cells are transparent; PGM and BMP have no "
            "alpha)"
        )
    for path in (image, yaml_path):
        check_output(path, force)


def _check_thresholds(occupied_thresh: float, free_thresh: float) -> None:
    if not (0.0 <= free_thresh < occupied_thresh <= 1.0):  # also False for NaN
        raise UsageError(
            "need 0 <= free threshold < occupied threshold <= 1, "
            f"got free {free_thresh} and occupied {occupied_thresh}"
        )


def transparent_grey(occupied_thresh: float, free_thresh: float) -> int:
    """Grey value stored under the transparent (unknown) pixels of a scale map.

    Nav2 ignores the grey of a transparent pixel, but ROS 1 ``map_server`` consults alpha only for
    pixels whose grey lies between the thresholds: a transparent pixel of grey 205 (p = 0.196)
    would load as *free* with ``free_thresh: 0.25``. So the grey is the one whose p = (255 - g)/255
    is nearest the middle of the two thresholds, strictly between them whenever any grey is.
    """
    middle = 0.5 * (occupied_thresh + free_thresh)
    greys = np.arange(256)
    p = (255 - greys) / 255
    inside = (p > free_thresh) & (p < occupied_thresh)
    candidates = greys[inside] if inside.any() else greys
    return int(candidates[np.argmin(np.abs((255 - candidates) / 255 - middle))])


def occupancy_percent(
    prob: npt.NDArray[np.float64],
    occupied_thresh: float | None = None,
    free_thresh: float | None = None,
) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.bool_]]:
    """Occupancy percentages of a probability map and its unknown cells, both shaped as ``prob``.

    ``prob``: shape (height, width), values in [0, 1], NaN unknown. Returns round(100 p) (half to
    even; 0 under unknown cells) as uint8 and the mask of NaN cells: what a ``raw`` image and an
    OccupancyGrid hold. With the thresholds, cells the map calls occupied are 100 and free 0, the
    others within 1..99 (:func:`raw_percent`). Raises ``ValueError`` for an array that is not 2-D
    or holds values outside [0, 1], which would otherwise wrap around in the 8-bit result.
    Computed in row strips: the temporaries stay a few MiB whatever the map's size.
    """
    prob = _checked(prob)
    percent = np.empty(prob.shape, dtype=np.uint8)
    unknown = np.empty(prob.shape, dtype=bool)
    for rows in _strips(prob):
        part = prob[rows]
        unknown[rows] = np.isnan(part)
        p = np.where(unknown[rows], 0.0, part)
        if occupied_thresh is None or free_thresh is None:
            percent[rows] = np.rint(100.0 * p).astype(np.uint8)
        else:
            percent[rows] = raw_percent(p, occupied_thresh, free_thresh)
    return percent, unknown


def raw_percent(
    p: npt.NDArray[np.float64], occupied_thresh: float, free_thresh: float
) -> npt.NDArray[np.uint8]:
    """A raw cell's value: 100 where the map calls it occupied, 0 where free, else round(100 p)
    within 1..99, so that the loaders that read only 100 as a wall and 0 as free (Nav2's
    costmap, AMCL) read the map's own classes."""
    between = np.clip(np.rint(100.0 * p), 1.0, 99.0)
    out = np.where(p >= occupied_thresh, 100.0, np.where(p <= free_thresh, 0.0, between))
    return out.astype(np.uint8)


def scale_grey_bounds(occupied_thresh: float, free_thresh: float) -> tuple[int, int]:
    """The largest grey that loads as occupied and the smallest that loads as free, under the
    strict comparisons (ROS 1, Nav2 Humble: p = (255 - grey) / 255 > occupied, < free), which
    the inclusive ones (Nav2 Jazzy) then take too. 0 and 255 when no grey is strictly beyond a
    threshold (1 and 0)."""
    greys = np.arange(256)
    p = (255 - greys) / 255
    occupied = greys[p > occupied_thresh]
    free = greys[p < free_thresh]
    return (int(occupied.max()) if occupied.size else 0), (int(free.min()) if free.size else 255)


#: Cells of a map turned into pixels at a time.
_STRIP_CELLS = 1 << 18


def _strips(prob: npt.NDArray[np.float64]) -> list[slice]:
    """Row slices of about :data:`_STRIP_CELLS` cells covering ``prob``."""
    height, width = prob.shape
    step = max(1, _STRIP_CELLS // max(width, 1))
    return [slice(r, min(height, r + step)) for r in range(0, height, step)]


def _checked(prob: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """``prob`` as a 2-D float64 array whose known values lie in [0, 1] (ValueError otherwise)."""
    prob = np.asarray(prob, dtype=np.float64)
    if prob.ndim != 2:
        raise ValueError(f"a probability map must be 2-D, got shape {prob.shape}")
    for rows in _strips(prob):
        part = prob[rows]
        if np.any(part < 0.0) or np.any(part > 1.0):  # NaN compares False
            raise ValueError("probabilities must lie in [0, 1] (NaN for unknown)")
    return prob


def map_pixels(
    prob: npt.NDArray[np.float64], mode: str, occupied_thresh: float, free_thresh: float
) -> npt.NDArray[np.uint8]:
    """The image of a probability map, top image row first.

    ``prob``: shape (height, width), row 0 the bottom of the map, values in [0, 1], NaN unknown.
    Returns uint8 of shape (height, width) for ``trinary`` and ``raw``, (height, width, 2) (grey,
    alpha) for ``scale``:

    - trinary: p >= occupied_thresh -> 0, p <= free_thresh -> 254, otherwise and NaN -> 205;
    - scale: grey round(255 (1 - p)) with alpha 255, moved for a cell the map calls occupied or
      free to a grey every loader reads as such (:func:`scale_grey_bounds`); NaN -> alpha 0
      (grey :func:`transparent_grey`);
    - raw: :func:`raw_percent` (100 occupied, 0 free, else round(100 p) within 1..99); NaN -> 255.

    Rounding is half to even. Raises :class:`UsageError` unless 0 <= free < occupied <= 1, and
    ``ValueError`` for an array that is not 2-D or holds values outside [0, 1]. The image is the
    only map-sized array made (1 byte a cell, 2 in scale mode): the rest goes in row strips.
    """
    if mode not in MAP_MODES:
        raise UsageError(f"unknown map mode '{mode}' (known: {', '.join(MAP_MODES)})")
    _check_thresholds(occupied_thresh, free_thresh)
    prob = _checked(prob)
    height, width = prob.shape
    image = np.empty((height, width, 2) if mode == "scale" else (height, width), dtype=np.uint8)
    hidden = transparent_grey(occupied_thresh, free_thresh)
    wall_grey, free_grey = scale_grey_bounds(occupied_thresh, free_thresh)
    for rows in _strips(prob):
        part = prob[rows]
        unknown = np.isnan(part)
        # NaN-free copy so the arithmetic below raises no warnings; unknown cells are overwritten
        p = np.where(unknown, 0.0, part)
        if mode == "trinary":
            grey = np.full(p.shape, UNKNOWN_GREY, dtype=np.uint8)
            grey[p <= free_thresh] = FREE_GREY
            grey[p >= occupied_thresh] = OCCUPIED_GREY
            grey[unknown] = UNKNOWN_GREY
            pixels: npt.NDArray[np.uint8] = grey
        elif mode == "raw":
            pixels = raw_percent(p, occupied_thresh, free_thresh)
            pixels[unknown] = RAW_UNKNOWN_GREY
        else:
            grey = np.rint(255.0 * (1.0 - p))
            grey = np.where(p >= occupied_thresh, np.minimum(grey, wall_grey), grey)
            grey = np.where(p <= free_thresh, np.maximum(grey, free_grey), grey).astype(np.uint8)
            grey[unknown] = hidden
            alpha = np.where(unknown, 0, 255).astype(np.uint8)
            pixels = np.stack([grey, alpha], axis=-1)
        # map row 0 is the bottom of the map, image row 0 the top
        image[height - rows.stop : height - rows.start] = pixels[::-1]
    return image


def _yaml_string(name: str) -> str:
    """``name`` as a YAML scalar: plain when that is unambiguous, else single-quoted."""
    text = name if _PLAIN_NAME.fullmatch(name) else "'" + name.replace("'", "''") + "'"
    try:
        same = yaml.safe_load(f"k: {text}") == {"k": name}
    except yaml.YAMLError:
        same = False
    if not same:
        raise UsageError(f"the file name {name!r} cannot be written in a map YAML")
    return text


def map_yaml_text(
    image_name: str, mode: str, spec: GridSpec, occupied_thresh: float, free_thresh: float
) -> str:
    """The YAML describing a map image, in the key order of Nav2's saver.

    ``image_name`` is written as given (callers pass the basename: loaders resolve it against the
    YAML's folder); ``origin`` is the world pose (metres, radians) of the lower-left corner of
    cell (0, 0), with yaw always 0.0. Numbers are written in full precision.
    """
    if not (spec.resolution_m > 0.0 and math.isfinite(spec.resolution_m)):
        raise ValueError(f"resolution must be a positive number of metres, got {spec.resolution_m}")
    origin = ", ".join(format_float(v) for v in (spec.origin_x_m, spec.origin_y_m, 0.0))
    return (
        f"image: {_yaml_string(image_name)}\n"
        f"mode: {mode}\n"
        f"resolution: {format_float(spec.resolution_m)}\n"
        f"origin: [{origin}]\n"
        "negate: 0\n"
        f"occupied_thresh: {format_float(occupied_thresh)}\n"
        f"free_thresh: {format_float(free_thresh)}\n"
    )


def write_map(
    image_path: Path,
    omap: OccupancyMap,
    *,
    mode: str = "trinary",
    occupied_thresh: float = 0.65,
    free_thresh: float = 0.25,
    force: bool = False,
    also: Sequence[ExtraOutput] = (),
) -> tuple[Path, Path]:
    """Write ``omap`` as ``image_path`` plus the YAML beside it; return (image, yaml) paths.

    ``also``: more files that belong with the map (a layer beside it), written in the same
    atomic block, so that all are written or none; the caller checks them beforehand.

    ``occupied_thresh`` / ``free_thresh`` are probabilities in [0, 1]: in ``trinary`` mode they
    classify cells and the YAML gets 0.65 / 0.196 regardless; in ``scale`` and ``raw`` modes they
    are written to the YAML as given. PGM output is binary P5 with maxval 255 and no comment
    (a 3 x 3 map is 20 bytes); PNG output is 8-bit grey, with alpha in scale mode.

    Raises :class:`UsageError` / :class:`OutputExistsError` as :func:`check_map_outputs` does and
    :class:`GridmapError` when a file cannot be written (then neither file is left behind).
    """
    check_map_outputs(image_path, mode, force)
    image_out, yaml_out = map_output_paths(image_path)
    if omap.prob.shape != omap.spec.shape:
        raise ValueError(
            f"probability array of shape {omap.prob.shape} for a grid of shape {omap.spec.shape}"
        )
    pixels = map_pixels(omap.prob, mode, occupied_thresh, free_thresh)
    if mode == "trinary":
        yaml_occupied, yaml_free = TRINARY_YAML_OCCUPIED_THRESH, TRINARY_YAML_FREE_THRESH
    else:
        yaml_occupied, yaml_free = occupied_thresh, free_thresh
    text = map_yaml_text(image_out.name, mode, omap.spec, yaml_occupied, yaml_free)

    targets = [image_out, yaml_out] + [path for paths, _ in also for path in paths]
    temps: list[Path] = []
    try:
        with atomic_outputs(targets) as temps:
            tmp_image, tmp_yaml = temps[:2]
            # the temporary name keeps the target's suffix, so Pillow picks PPM (P5) or PNG;
            # uint8 (H, W) becomes mode L and (H, W, 2) mode LA
            Image.fromarray(pixels).save(tmp_image)
            tmp_yaml.write_text(text, encoding="utf-8")
            at = 2
            for paths, write in also:
                write(temps[at : at + len(paths)])
                at += len(paths)
    except OSError as exc:
        failed = _output_named_by(exc, list(zip(temps, targets, strict=False)))
        raise GridmapError(
            f"{failed or image_out}: cannot write the map: {exc.strerror or exc}"
        ) from exc
    return image_out, yaml_out


def _output_named_by(exc: OSError, pairs: list[tuple[Path, Path]]) -> Path | None:
    """The output an OSError is about, naming the target rather than its temporary file."""
    for name in (exc.filename2, exc.filename):
        if name is None:
            continue
        for tmp, target in pairs:
            if str(name) in (str(tmp), str(target)):
                return target
    return None
