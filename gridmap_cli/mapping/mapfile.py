"""Loader for map_server maps (YAML + image), reading them as the real loaders do.

``docs/map-format.md`` gives the rules; three loaders differ in details, chosen by ``flavour``:

``ros1``
    ROS 1 ``map_server`` (SDL_image). Thresholds strict (p > occupied, p < free). Trinary
    averages every channel *including alpha* into the grey value; scale and raw average the
    colour channels only. In scale mode alpha is consulted only for pixels between the
    thresholds: such a pixel with alpha 0 is unknown, else 1 + 98 ratio truncated (the C++
    conversion to an integer); a transparent pixel that is clearly dark or light stays occupied
    or free. Without an alpha channel ROS 1 reads the last channel as alpha: for RGB images
    that is blue (a quirk reproduced here), for grey images there is none. Raw applies
    ``negate`` and truncates the channel average.
``nav2-humble``
    Nav2 Humble (GraphicsMagick). Thresholds strict. Trinary averages R, G, B and alpha; scale
    reads any pixel that is not fully opaque (alpha < 255) as unknown before thresholding, and
    in-between pixels as round(100 ratio) (half to even, C's ``rint``). Raw ignores ``negate``.
``nav2-jazzy`` (default; Jazzy and later)
    Thresholds inclusive (p >= occupied, p <= free). The image is first reduced to one 8-bit
    grey value; in trinary *and* scale modes any pixel with alpha < 255 is unknown; in-between
    scale pixels become round(100 ratio) (half away from zero). Raw ignores ``negate`` and alpha.

Everywhere p = (255 - g) / 255 (``negate: 1``: p = g / 255), ratio = (p - free) / (occupied -
free), and raw reads a grey 0..100 as that occupancy and anything else as unknown (ROS 1 would
store 101..254 as wrapped int8 garbage; here those are unknown too, so occupancy is always
-1 or 0..100). Grey pixels count as R = G = B; colour pixels are averaged (Jazzy really uses a
luminance, which differs only for coloured pixels); palette images are read by their colours
(ROS 1 would read palette indices). Image row j (top = 0) is map row height-1-j.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt
from PIL import Image, UnidentifiedImageError

from gridmap_cli.errors import InputFileError, UsageError
from gridmap_cli.mapping.grid import GridSpec
from gridmap_cli.yamlfile import number, read_yaml_mapping

LOADER_FLAVOURS = ("ros1", "nav2-humble", "nav2-jazzy")
DEFAULT_FLAVOUR = "nav2-jazzy"
MAP_MODES = ("trinary", "scale", "raw")

OCCUPIED = 100
FREE = 0
UNKNOWN = -1

#: :meth:`LoadedMap.occupied_mask` counts a cell as occupied from this occupancy on. Trinary maps
#: hold only 0 / 100 / -1; in scale maps 50 is the middle of the band between the thresholds.
DEFAULT_OCCUPIED_MIN = 50

_REQUIRED_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
# Pillow modes read as 8-bit colour (+ alpha); others (16-bit, float, CMYK...) are refused
_MODES_READ = {"1", "L", "LA", "La", "P", "PA", "RGB", "RGBA", "RGBa", "RGBX"}


@dataclass(frozen=True)
class LoadedMap:
    """A map as a map_server loader hands it to its users.

    ``occupancy``: int8, shape (height, width), row 0 the bottom of the map (smallest y, the
    row of ``spec``'s origin), values -1 unknown or 0..100. ``spec`` holds the origin x, y
    (metres, world frame) and the resolution (metres per cell); ``origin_yaw_rad`` is the YAML's
    yaw, which gridmap, like costmaps and AMCL, ignores.
    """

    spec: GridSpec
    occupancy: npt.NDArray[np.int8]
    image_path: Path
    mode: str
    negate: bool
    occupied_thresh: float
    free_thresh: float
    origin_yaw_rad: float = 0.0
    #: The image's colour and alpha as read (top row first, see ``_read_image``); load_map keeps
    #: them for scale maps, whose pixels state p itself (:meth:`stored_probability`).
    pixels: tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint8] | None] | None = field(
        default=None, repr=False, compare=False
    )

    def occupied_mask(self, min_occupancy: int = DEFAULT_OCCUPIED_MIN) -> npt.NDArray[np.bool_]:
        """True where occupancy >= ``min_occupancy``; shape (height, width); unknown is False."""
        return np.asarray(self.occupancy >= min_occupancy)

    def probability(self) -> npt.NDArray[np.float64]:
        """Occupancy / 100 as float, NaN where unknown; shape (height, width), row 0 at bottom."""
        prob = self.occupancy.astype(np.float64) / 100.0
        prob[self.occupancy < 0] = np.nan
        return prob

    def stored_probability(self) -> npt.NDArray[np.float64]:
        """The occupancy probability the map file states for each cell; NaN where unknown.

        Shape (height, width), row 0 at the bottom. A ``scale`` map stores p itself: p = (255 -
        g) / 255 (g / 255 with ``negate``) from each pixel's grey (the mean of its colour
        channels, unrounded), with any pixel not fully opaque unknown (as Nav2 reads it).
        ``trinary`` and ``raw`` maps state only what the loader makes of them:
        :meth:`probability` (trinary: 0 or 1), as does a map made without its ``pixels``.
        """
        if self.mode != "scale" or self.pixels is None:
            return self.probability()
        colour, alpha = self.pixels
        p = _grey_probability(colour.astype(np.float64).mean(axis=2), self.negate)
        if alpha is not None:
            p[alpha < 255] = np.nan
        return np.ascontiguousarray(p[::-1])


def load_map(yaml_path: Path, flavour: str = DEFAULT_FLAVOUR) -> LoadedMap:
    """Load a map_server YAML and its image as the ``flavour`` of loader would.

    The image path is taken relative to the YAML's folder unless absolute. Raises
    :class:`UsageError` for an unknown flavour and :class:`InputFileError` (naming the file and,
    where known, the YAML line) for a missing or malformed YAML, a missing key, a resolution that
    is not a positive finite number, an origin that is not three finite numbers, an unknown mode,
    ``occupied_thresh <= free_thresh``, or an image that does not exist or cannot be read.
    """
    if flavour not in LOADER_FLAVOURS:
        raise UsageError(f"unknown map loader '{flavour}' (known: {', '.join(LOADER_FLAVOURS)})")
    yaml_path = Path(yaml_path)
    doc, lines = read_yaml_mapping(
        yaml_path, "a map YAML", "not a map YAML: expected a mapping of keys to values"
    )

    def fail(key: str, detail: str) -> InputFileError:
        return InputFileError(yaml_path, detail, line=lines.get(key))

    for key in _REQUIRED_KEYS:
        if key not in doc:
            raise InputFileError(yaml_path, f"missing key '{key}'")

    resolution = number(doc["resolution"])
    if resolution is None or not (math.isfinite(resolution) and resolution > 0.0):
        raise fail("resolution", f"resolution must be a positive number, got {doc['resolution']!r}")
    origin = doc["origin"]
    values = [number(v) for v in origin] if isinstance(origin, list) else []
    if len(values) != 3 or not all(v is not None and math.isfinite(v) for v in values):
        raise fail("origin", f"origin must be three finite numbers [x, y, yaw], got {origin!r}")
    x0, y0, yaw = (float(v) for v in values if v is not None)
    negate = doc["negate"]
    # yaml-cpp loaders accept an integer (non-zero = true) or a boolean
    if not isinstance(negate, int):
        raise fail("negate", f"negate must be 0 or 1, got {negate!r}")
    thresholds: dict[str, float] = {}
    for key in ("occupied_thresh", "free_thresh"):
        value = number(doc[key])
        if value is None or not math.isfinite(value):
            raise fail(key, f"{key} must be a number, got {doc[key]!r}")
        thresholds[key] = value
    occupied_thresh, free_thresh = thresholds["occupied_thresh"], thresholds["free_thresh"]
    if occupied_thresh <= free_thresh:
        raise fail(
            "occupied_thresh",
            f"occupied_thresh ({occupied_thresh}) must be greater than free_thresh ({free_thresh})",
        )
    mode = doc.get("mode", "trinary")
    if mode not in MAP_MODES:
        raise fail("mode", f"unknown mode {mode!r} (known: {', '.join(MAP_MODES)})")
    image_name = doc["image"]
    if not isinstance(image_name, str) or not image_name:
        raise fail("image", f"image must be a file name, got {image_name!r}")
    image_path = yaml_path.parent / image_name  # an absolute name replaces the folder
    if not image_path.is_file():
        what = "does not exist" if not image_path.exists() else "is not a file"
        raise fail("image", f"image {image_path} {what}")

    colour, alpha = _read_image(image_path)
    occupancy = pixels_to_occupancy(
        colour, alpha, mode, flavour, bool(negate), occupied_thresh, free_thresh
    )
    height, width = occupancy.shape
    return LoadedMap(
        spec=GridSpec(x0, y0, resolution, width, height),
        occupancy=np.ascontiguousarray(occupancy[::-1]),
        image_path=image_path,
        mode=mode,
        negate=bool(negate),
        occupied_thresh=occupied_thresh,
        free_thresh=free_thresh,
        origin_yaw_rad=yaw,
        pixels=(colour, alpha) if mode == "scale" else None,
    )


def _read_image(
    path: Path,
) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint8] | None]:
    """Colour channels, shape (H, W, 1) grey or (H, W, 3) RGB, and alpha (H, W) or None.

    Top image row first, as stored.
    """
    try:
        with Image.open(path) as img:
            img.load()
            if img.mode not in _MODES_READ:
                raise InputFileError(
                    path,
                    f"unsupported image mode '{img.mode}' "
                    "(map images are 8-bit grey or colour, optionally with alpha)",
                )
            if img.mode in ("P", "PA"):
                has_alpha = img.mode == "PA" or img.has_transparency_data
                img_rgb = img.convert("RGBA" if has_alpha else "RGB")
            elif img.mode == "1":
                img_rgb = img.convert("L")
            elif img.mode in ("La", "RGBa"):
                # premultiplied alpha: undo it so the colours are what the file means
                img_rgb = img.convert("LA" if img.mode == "La" else "RGBA")
            elif img.mode == "RGBX":
                img_rgb = img.convert("RGB")
            else:
                img_rgb = img
            array = np.asarray(img_rgb, dtype=np.uint8)
    except (
        UnidentifiedImageError,
        OSError,
        Image.DecompressionBombError,
        ValueError,
        SyntaxError,
    ) as exc:
        # Pillow refuses images over ~179 M pixels; gridmap's own maps stay under 1e8 cells.
        # A damaged header raises ValueError (a PGM size of b'garbage') or SyntaxError (PNG).
        raise InputFileError(path, f"cannot read the image: {exc}") from exc
    if array.ndim == 2:
        return array[:, :, np.newaxis], None
    if array.shape[2] in (2, 4):
        return array[:, :, :-1], array[:, :, -1]
    return array, None


def pixels_to_occupancy(
    colour: npt.NDArray[np.uint8],
    alpha: npt.NDArray[np.uint8] | None,
    mode: str,
    flavour: str,
    negate: bool,
    occupied_thresh: float,
    free_thresh: float,
) -> npt.NDArray[np.int8]:
    """Occupancy of each pixel as the ``flavour`` of loader computes it (rules in module doc).

    ``colour``: uint8, shape (H, W, 1) grey or (H, W, 3) RGB; ``alpha``: uint8 (H, W) or None for
    an image without alpha. Returns int8 of shape (H, W) in *image* order (top row first),
    values -1 or 0..100.
    """
    if flavour not in LOADER_FLAVOURS:
        raise UsageError(f"unknown map loader '{flavour}' (known: {', '.join(LOADER_FLAVOURS)})")
    if mode not in MAP_MODES:
        raise ValueError(f"unknown map mode {mode!r}")
    # loaders see grey images as R = G = B (SDL_image and GraphicsMagick expand them)
    rgb = np.broadcast_to(colour, (*colour.shape[:2], 3)).astype(np.float64)
    opaque = np.full(colour.shape[:2], 255.0)
    a = opaque if alpha is None else alpha.astype(np.float64)

    if flavour == "nav2-jazzy":
        # one 8-bit grey value per pixel before anything else
        grey = np.rint(rgb.mean(axis=2))
    elif mode == "trinary" and alpha is not None:
        grey = (rgb.sum(axis=2) + a) / 4.0
    else:
        grey = rgb.mean(axis=2)

    if mode == "raw":
        if flavour == "ros1":
            raw = np.trunc(255.0 - grey if negate else grey)
        elif flavour == "nav2-humble":
            raw = _round_half_away(grey)
        else:
            raw = grey
        return np.where((raw >= 0) & (raw <= 100), raw, UNKNOWN).astype(np.int8)

    p = _grey_probability(grey, negate)
    if flavour == "nav2-jazzy":
        occupied, free = p >= occupied_thresh, p <= free_thresh
    else:
        occupied, free = p > occupied_thresh, p < free_thresh
    between = ~(occupied | free)
    out = np.full(p.shape, UNKNOWN, dtype=np.int8)
    out[occupied] = OCCUPIED
    out[free] = FREE

    if mode == "scale":
        ratio = (p - free_thresh) / (occupied_thresh - free_thresh)
        if flavour == "ros1":
            # with no alpha channel ROS 1 takes the last channel as alpha (blue for RGB)
            ros_alpha = rgb[:, :, 2] if alpha is None and colour.shape[2] == 3 else a
            value = np.trunc(1.0 + 98.0 * ratio)
            out[between] = np.where(ros_alpha[between] == 0, UNKNOWN, value[between])
        elif flavour == "nav2-humble":
            out[between] = np.rint(100.0 * ratio[between])
            out[a < 255] = UNKNOWN
        else:
            out[between] = _round_half_away(100.0 * ratio[between])
    if flavour == "nav2-jazzy" and mode in ("trinary", "scale"):
        out[a < 255] = UNKNOWN
    return out


def _grey_probability(grey: npt.NDArray[np.float64], negate: bool) -> npt.NDArray[np.float64]:
    """p of a grey value 0..255: dark is occupied, unless ``negate``."""
    return grey / 255.0 if negate else (255.0 - grey) / 255.0


def _round_half_away(x: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """C's ``round``: halves away from zero (numpy's ``rint`` rounds them to even)."""
    # floor(|x| + 0.5) would round 0.49999999999999994 up, as the addition itself rounds
    ax = np.abs(x)
    whole = np.floor(ax)
    return np.asarray(np.sign(x) * (whole + (ax - whole >= 0.5)), dtype=np.float64)
