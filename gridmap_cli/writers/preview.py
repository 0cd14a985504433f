"""A preview of a map for people: occupancy in grey, unknown in a visible colour, the robot's
tracks drawn on top.

Never a map_server image (the map's own PNG/PGM stays exactly what the loaders expect): a
separate RGB PNG. Scale maps show unknown as transparent, which most viewers draw white, so a
scale map looks as if its unknown area were free; here unknown is pale blue.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
from PIL import Image, ImageDraw

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


def write_preview(path: Path, omap: OccupancyMap, tracks: list[DrawnTrack]) -> Path:
    """Write the preview PNG at ``path`` (atomically); tracks are drawn 1 pixel wide, in order."""
    spec = omap.spec
    image = Image.fromarray(preview_pixels(omap), mode="RGB")
    draw = ImageDraw.Draw(image)
    for track in tracks:
        col = (track.x_m - spec.origin_x_m) / spec.resolution_m
        row = spec.height - (track.y_m - spec.origin_y_m) / spec.resolution_m
        points = [(float(c), float(r)) for c, r in zip(col, row, strict=True)]
        if len(points) > 1:
            draw.line(points, fill=track.rgb, width=1)
    try:
        with atomic_outputs([path]) as temps:
            image.save(temps[0], format="PNG")
    except OSError as exc:
        raise GridmapError(f"{path}: cannot write the preview: {exc.strerror or exc}") from exc
    return path
