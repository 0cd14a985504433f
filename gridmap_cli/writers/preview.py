"""A preview of a map for people: occupancy in grey, unknown in a visible colour, the robot's
tracks drawn on top.

Never a map_server image (the map's own PNG/PGM stays exactly what the loaders expect): a
separate RGB PNG. Scale maps show unknown as transparent, which most viewers draw white, so a
scale map looks as if its unknown area were free; here unknown is pale blue. With a pose-spread
layer (:mod:`.spread_layer`) the cells are tinted orange by their spread, from none at
:data:`TINT_FROM_M` to full at :data:`TINT_FULL_M`. A legend under the map says what each colour
means.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
from PIL import Image, ImageDraw, ImageFont

from gridmap_cli.atomic import atomic_outputs
from gridmap_cli.errors import GridmapError
from gridmap_cli.geometry import compose, inverse
from gridmap_cli.mapping.grid import OccupancyMap
from gridmap_cli.records import PoseTrack

#: Colours (RGB): cells never observed, and the two tracks.
UNKNOWN_RGB = (196, 216, 240)
ODOMETRY_RGB = (220, 40, 30)
REFERENCE_RGB = (20, 150, 60)
SCAN_MATCHED_RGB = (120, 50, 200)
#: The tint of cells seen from poorly placed poses, and the spreads (m) it fades in between:
#: under a cell or two nothing shows; at a corridor's half width the cell is fully tinted.
SPREAD_RGB = (245, 130, 20)
TINT_FROM_M = 0.1
TINT_FULL_M = 1.0
#: The strongest tint: the grey of the map stays readable under it.
TINT_MAX = 0.6
#: Height of one legend line, pixels.
LEGEND_LINE_PX = 14


#: Legend lines: a colour and what it means.
Entries = list[tuple[tuple[int, int, int], str]]


@dataclass(frozen=True)
class DrawnTrack:
    """A track to draw: positions (N,) in the map's frame, and its colour."""

    x_m: npt.NDArray[np.float64]
    y_m: npt.NDArray[np.float64]
    rgb: tuple[int, int, int]


def drawn(track: PoseTrack, rgb: tuple[int, int, int]) -> DrawnTrack:
    """A track drawn where its poses are (the track the map was built with)."""
    return DrawnTrack(track.x_m, track.y_m, rgb)


def placed_at(track: PoseTrack, anchor: PoseTrack, rgb: tuple[int, int, int]) -> DrawnTrack | None:
    """``track`` moved rigidly so that its pose at the first stamp both tracks cover lies on
    ``anchor``'s pose there; only its part within ``anchor``'s time span.

    Two tracks of one run live in different frames (odometry starts at its own origin, the
    reference in the world); drawn on one map, the other track is placed by the pose both have at
    the first stamp they share, the way ``evaluate`` places an odometry-frame map. None when the
    tracks do not overlap in time.
    """
    if len(track) == 0 or len(anchor) == 0:
        return None
    t0 = max(int(track.stamp_ns[0]), int(anchor.stamp_ns[0]))
    if t0 > min(int(track.stamp_ns[-1]), int(anchor.stamp_ns[-1])):
        return None

    def pose_at(t: PoseTrack) -> npt.NDArray[np.float64]:
        k = int(np.searchsorted(t.stamp_ns, t0))
        return np.array([t.x_m[k], t.y_m[k], t.theta_rad[k]])

    a, b = pose_at(anchor), pose_at(track)
    shift = compose(a[:1], a[1:2], a[2:], *inverse(b[:1], b[1:2], b[2:]))
    x, y, _ = compose(*shift, track.x_m, track.y_m, track.theta_rad)
    inside = (track.stamp_ns >= anchor.stamp_ns[0]) & (track.stamp_ns <= anchor.stamp_ns[-1])
    return DrawnTrack(x[inside], y[inside], rgb)


def preview_pixels(omap: OccupancyMap) -> npt.NDArray[np.uint8]:
    """(H, W, 3) RGB, top row first: grey = 255 (1 - p) for observed cells (black walls, white
    free space, the uncertain between), pale blue for cells never observed."""
    prob = omap.prob[::-1]
    grey = np.clip(np.round(255.0 * (1.0 - np.nan_to_num(prob, nan=0.5))), 0, 255)
    rgb = np.repeat(grey.astype(np.uint8)[:, :, None], 3, axis=2)
    rgb[np.isnan(prob)] = UNKNOWN_RGB
    return rgb


def tinted(rgb: npt.NDArray[np.uint8], spread_m: npt.NDArray[np.float64]) -> npt.NDArray[np.uint8]:
    """``rgb`` (H, W, 3, top row first) tinted towards :data:`SPREAD_RGB` by the spread layer
    ``spread_m`` (H, W, row 0 at the bottom; NaN untouched)."""
    spread = spread_m[::-1]
    weight = np.clip((np.nan_to_num(spread, nan=0.0) - TINT_FROM_M) / (TINT_FULL_M - TINT_FROM_M),
                     0.0, 1.0) * TINT_MAX  # fmt: skip
    mixed = rgb * (1.0 - weight[:, :, None]) + np.asarray(SPREAD_RGB) * weight[:, :, None]
    out: npt.NDArray[np.uint8] = np.rint(mixed).astype(np.uint8)
    return out


def legend_entries(tracks: list[DrawnTrack], spread: bool) -> Entries:
    """The legend's lines: a colour and what it means, for the colours this preview uses."""
    names = {
        ODOMETRY_RGB: "odometry track",
        REFERENCE_RGB: "reference track (the log's true or corrected poses)",
        SCAN_MATCHED_RGB: "scan-matched or pose-graph track",
    }
    entries = [(UNKNOWN_RGB, "unknown: no reading reached it"),
               ((0, 0, 0), "grey: 1 - p, black occupied, white free")]  # fmt: skip
    seen: list[tuple[int, int, int]] = []
    for track in tracks:
        if track.rgb in names and track.rgb not in seen:
            seen.append(track.rgb)
    entries += [(rgb, names[rgb]) for rgb in seen]
    if spread:
        entries.append(
            (
                SPREAD_RGB,
                f"orange: pose spread of the readings, from {TINT_FROM_M:g} m (none) to "
                f"{TINT_FULL_M:g} m (full)",
            )
        )
    return entries


def _with_legend(
    image: Image.Image, entries: list[tuple[tuple[int, int, int], str]]
) -> Image.Image:
    """``image`` with a white band under it holding one line per entry."""
    font = ImageFont.load_default()
    widths = [int(ImageDraw.Draw(image).textlength(text, font=font)) for _, text in entries]
    width = max(image.width, 24 + max(widths, default=0))
    out = Image.new("RGB", (width, image.height + LEGEND_LINE_PX * len(entries) + 4), "white")
    out.paste(image, (0, 0))
    draw = ImageDraw.Draw(out)
    for k, (rgb, text) in enumerate(entries):
        top = image.height + 2 + k * LEGEND_LINE_PX
        draw.rectangle((4, top + 2, 14, top + 11), fill=rgb, outline=(90, 90, 90))
        draw.text((20, top), text, fill=(0, 0, 0), font=font)
    return out


def write_preview(
    path: Path,
    omap: OccupancyMap,
    tracks: list[DrawnTrack],
    spread_m: npt.NDArray[np.float64] | None = None,
) -> Path:
    """Write the preview PNG at ``path`` (atomically): the map, tinted by ``spread_m`` (the
    pose-spread layer, shape ``omap.spec.shape``) when given, the tracks drawn 1 pixel wide in
    order, and the legend under it (the map's pixels keep their rows and columns)."""
    spec = omap.spec
    pixels = preview_pixels(omap)
    if spread_m is not None:
        pixels = tinted(pixels, spread_m)
    image = Image.fromarray(pixels, mode="RGB")
    draw = ImageDraw.Draw(image)
    for track in tracks:
        col = (track.x_m - spec.origin_x_m) / spec.resolution_m
        row = spec.height - (track.y_m - spec.origin_y_m) / spec.resolution_m
        points = [(float(c), float(r)) for c, r in zip(col, row, strict=True)]
        if len(points) > 1:
            draw.line(points, fill=track.rgb, width=1)
    image = _with_legend(image, legend_entries(tracks, spread_m is not None))
    try:
        with atomic_outputs([path]) as temps:
            image.save(temps[0], format="PNG")
    except OSError as exc:
        raise GridmapError(f"{path}: cannot write the preview: {exc.strerror or exc}") from exc
    return path
