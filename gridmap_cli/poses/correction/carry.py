"""Carry a correction known at some poses (anchors) to every pose of a denser track.

A scan-matched or optimised pose is known at the scans (or keyframes); the track between them
is the denser base track (the odometry, or the scan-matched track) with the correction spread
over the gap. At a stamp between anchors ``k`` and ``k + 1`` two predictions meet: the base
carried rigidly from anchor ``k`` (``S_k (+) P_k^-1 (+) P(t)``, ``S`` corrected, ``P`` base) and
from anchor ``k + 1``. The pose is their blend (x and y linear, heading along the shorter arc)
with the weight ``s``, the share of the base's *motion* between the two anchors done by ``t``
(path length plus ``TURN_M`` metres per radian turned), not the share of the time.

Why motion and why poses:

- odometry error grows with motion, not with time: a robot that stood for two seconds and then
  drove for one gathered its error in the last second; where stamps are bunched (a log whose
  clock runs in bursts) the time share is nonsense while the motion share still holds;
- blending the two predicted poses, rather than the two corrections as transforms of the whole
  frame, keeps the lever arm of a heading change at the distance travelled since the anchor:
  a correction of the frame turns about the frame's origin, which may be tens of metres away
  once the odometry has drifted, and interpolating its (x, y, theta) swings the pose along
  that arm.

Before the first anchor and after the last the nearest anchor carries the base rigidly. Where
the base did not move between two anchors, the share of time stands in.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import compose, inverse, wrap_angle

FloatArray = npt.NDArray[np.float64]

#: Metres of motion a radian of turning counts as when the correction is spread.
TURN_M = 1.0


def carry(
    stamp_ns: npt.NDArray[np.int64],
    base: tuple[FloatArray, FloatArray, FloatArray],
    anchor_ns: npt.NDArray[np.int64],
    anchor_base: tuple[FloatArray, FloatArray, FloatArray],
    anchor_fixed: tuple[FloatArray, FloatArray, FloatArray],
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Corrected poses (x, y, theta), shape (M,) each, at ``stamp_ns`` (M,, increasing).

    ``base``: the base track's poses at ``stamp_ns``; ``anchor_ns`` (K,, increasing): the
    anchors' stamps, ``anchor_base`` the base's poses there and ``anchor_fixed`` the corrected
    ones (K,) each. See the module text.
    """
    bx, by, bth = (np.asarray(v, dtype=np.float64) for v in base)
    n_anchor = len(anchor_ns)
    ix, iy, ith = inverse(*anchor_base)
    # each anchor's correction as a frame change: fixed (+) base^-1
    cx, cy, cth = compose(*anchor_fixed, ix, iy, ith)
    if n_anchor == 1:
        return compose(cx[0], cy[0], cth[0], bx, by, bth)
    k = np.clip(np.searchsorted(anchor_ns, stamp_ns, side="right") - 1, 0, n_anchor - 2)
    fx, fy, fth = compose(cx[k], cy[k], cth[k], bx, by, bth)
    gx, gy, gth = compose(cx[k + 1], cy[k + 1], cth[k + 1], bx, by, bth)
    steps = np.hypot(np.diff(bx), np.diff(by)) + TURN_M * np.abs(wrap_angle(np.diff(bth)))
    travel = np.concatenate([[0.0], np.cumsum(steps)])
    at = np.interp(anchor_ns.astype(np.float64), stamp_ns.astype(np.float64), travel)
    moved = at[k + 1] - at[k]
    span = (anchor_ns[k + 1] - anchor_ns[k]).astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        by_motion = (travel - at[k]) / moved
        by_time = (stamp_ns - anchor_ns[k]).astype(np.float64) / span
    s = np.clip(np.where(moved > 1e-9, by_motion, np.where(span > 0, by_time, 0.0)), 0.0, 1.0)
    x = fx + s * (gx - fx)
    y = fy + s * (gy - fy)
    th = wrap_angle(fth + s * wrap_angle(gth - fth))
    return np.asarray(x), np.asarray(y), th
