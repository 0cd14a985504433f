"""How far a pose track is from a reference: absolute and relative errors, as evo computes them.

Both tracks are given at the same stamps (shape (N,) each). The absolute error (evo_ape with
``--align``) compares the poses after the rigid planar motion that best lays the track's
positions on the reference's (least squares, no scale: Umeyama's method in 2D). The relative
error (evo_rpe with ``--delta D --delta_unit m``) compares the motion between pose pairs D metres
apart along the reference path, so it does not depend on where the errors began.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import compose, inverse, wrap_angle
from gridmap_cli.poses.odometry_error import travelled
from gridmap_cli.records import PoseTrack

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class TrackError:
    """Errors of a track against a reference.

    ``ape_rmse_m``, ``ape_max_m``: position error after alignment (metres). ``ape_heading_deg``:
    RMS heading error after alignment. ``rpe_per_m``: RMS relative translation error per metre
    of the reference's travel (0.02 = 2 cm per metre) over ``delta_m``; ``rpe_heading_deg_per_m``
    the same for heading. ``alignment``: the pose (x, y, theta) of the track's frame in the
    reference's frame.
    """

    ape_rmse_m: float
    ape_max_m: float
    ape_heading_deg: float
    rpe_per_m: float
    rpe_heading_deg_per_m: float
    delta_m: float
    alignment: tuple[float, float, float]


def align_se2(track: PoseTrack, reference: PoseTrack) -> tuple[float, float, float]:
    """The rigid motion (x, y, theta) that best maps ``track``'s positions onto ``reference``'s."""
    a = np.column_stack([track.x_m, track.y_m])
    b = np.column_stack([reference.x_m, reference.y_m])
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    h = (a - ma).T @ (b - mb)
    # the 2D rotation maximising trace(R h): angle of (h01 - h10, h00 + h11)
    theta = math.atan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
    c, s = math.cos(theta), math.sin(theta)
    tx = mb[0] - (c * ma[0] - s * ma[1])
    ty = mb[1] - (s * ma[0] + c * ma[1])
    return float(tx), float(ty), theta


def transformed(track: PoseTrack, pose: tuple[float, float, float]) -> PoseTrack:
    """``track`` seen from a frame in which its own frame sits at ``pose``."""
    n = len(track)
    x, y, th = compose(
        np.full(n, pose[0]), np.full(n, pose[1]), np.full(n, pose[2]),
        track.x_m, track.y_m, track.theta_rad,
    )  # fmt: skip
    return PoseTrack(stamp_ns=track.stamp_ns, x_m=x, y_m=y, theta_rad=th)


def track_error(track: PoseTrack, reference: PoseTrack, delta_m: float = 5.0) -> TrackError:
    """APE and RPE of ``track`` against ``reference`` (same stamps)."""
    if len(track) != len(reference) or len(track) < 2:
        raise ValueError("track and reference need the same stamps, at least two")
    pose = align_se2(track, reference)
    aligned = transformed(track, pose)
    dist = np.hypot(aligned.x_m - reference.x_m, aligned.y_m - reference.y_m)
    head = wrap_angle(aligned.theta_rad - reference.theta_rad)
    along, _ = travelled(reference)
    j = np.searchsorted(along, along + delta_m, side="left")
    i = np.flatnonzero(j < len(reference))
    j = j[i]
    if len(i) == 0:
        rpe, rpe_head = math.nan, math.nan
    else:
        rel_t = _relative(track, i, j)
        rel_r = _relative(reference, i, j)
        ex, ey, eth = compose(*inverse(*rel_r), *rel_t)
        span = along[j] - along[i]
        rpe = float(np.sqrt(np.mean((np.hypot(ex, ey) / span) ** 2)))
        rpe_head = float(np.degrees(np.sqrt(np.mean((eth / span) ** 2))))
    return TrackError(
        ape_rmse_m=float(np.sqrt(np.mean(dist**2))),
        ape_max_m=float(dist.max()),
        ape_heading_deg=float(np.degrees(np.sqrt(np.mean(head**2)))),
        rpe_per_m=rpe,
        rpe_heading_deg_per_m=rpe_head,
        delta_m=delta_m,
        alignment=pose,
    )


def _relative(
    track: PoseTrack, i: npt.NDArray[np.intp], j: npt.NDArray[np.intp]
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The motion from pose i to pose j, in pose i's frame."""
    inv = inverse(track.x_m[i], track.y_m[i], track.theta_rad[i])
    return compose(*inv, track.x_m[j], track.y_m[j], track.theta_rad[j])
