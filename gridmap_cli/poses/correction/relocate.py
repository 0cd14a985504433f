"""A scan the odometry lost: found again on the local map by a correlative search.

The scan matcher starts GICP from the odometry's guess and from a few headings around it, and
takes no correction beyond a heading bound. Where the odometry is off by more than that, no
start holds: a sparse log that turns 30 degrees between scans with a heading error of half of
it, or a log whose odometry messages stop while the robot turns (a corrected CARMEN log then
has no odometry motion at all across the gap). Keeping the odometry's step there turns every
later pose by the error (a map bent at one scan), which a loop closure can only straighten if
the robot comes back.

The correlative search (:mod:`.correlative`; a real-time correlative matcher as Cartographer's
local SLAM has one) scores every pose of a window around the guess on a likelihood grid of the
local map, the translation within the matcher's correction bound. GICP from the best pose is
then judged by the matcher's own inlier test, and a turn beyond the heading bound also by the
fit the log's scans usually reach (:func:`typical_fit`). The heading window is what the odometry
can have lost (:data:`GAP_INTERVALS`): searched all round everywhere, a scan half in new space
(leaving a corridor) fits the corridor's other direction about as well as its own, and a
stale or mis-stamped scan (one that fits only well off its neighbours' heading while the robot
turns in place) would be taken where it fits, not where the robot was.
"""

from __future__ import annotations

import bisect
import math
from typing import Protocol

import numpy as np
import numpy.typing as npt
import small_gicp
from scipy.spatial import cKDTree

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.poses.correction.correlative import LikelihoodGrid, search
from gridmap_cli.poses.correction.sheet_gicp import (
    placed_points,
    register,
)

FloatArray = npt.NDArray[np.float64]
Pose = tuple[float, float, float]
#: GICP from a start: (inlier fraction, pose, Hessian (6, 6)).
Registration = tuple[float, Pose, FloatArray]

#: The likelihood grid's cell and sigma (m), as the loop closure's.
CELL_M = 0.1
#: The widest translation window (m) the grid serves, either side.
REACH_M = 2.0
#: The score a pose needs to start GICP; the inlier test then decides, as for any match.
MIN_SCORE = 0.3
#: Scan points farther than this (m) are not scored: they would need a finer heading step.
RANGE_M = 15.0
#: Matches needed before the log's usual fit is known; until then a turn beyond the matcher's
#: heading bound needs a perfect fit.
MIN_MATCHES = 10
#: A lost scan's heading window: all round across a gap in the odometry (the step spans this
#: many of its usual intervals, :func:`usual_interval`: a corrected CARMEN log keeps no motion
#: across one); twice the heading bound where the robot moved at least ``MOVED_M``; within the
#: bound where it did not (a robot that stood cannot have lost more than the retries cover: a
#: scan that fits only turned further is out of place, stale or mis-stamped, and keeping the
#: odometry is right). The window bounds the answer, not only the search: GICP from the best
#: pose must stay inside it.
GAP_INTERVALS = 10.0
MOVED_M = 0.01


class MapToSearch(Protocol):
    """A local map as the search takes it (the scan matcher's, :class:`.local_map.LocalMap`, or scan
    odometry's keyframes): GICP's target and tree, the 2-D points' tree, and the
    likelihood grid, None until built here."""

    cloud: small_gicp.PointCloud | None
    tree: small_gicp.KdTree | None
    tree2d: cKDTree | None
    grid: LikelihoodGrid | None


class Settings(Protocol):
    """What GICP and the inlier test take from the scan matcher's settings."""

    @property
    def correspondence_m(self) -> float: ...
    @property
    def max_iterations(self) -> int: ...
    @property
    def inlier_m(self) -> float: ...


def odometry_gaps(
    odometry_ns: npt.NDArray[np.int64], scans_ns: npt.NDArray[np.int64]
) -> npt.NDArray[np.bool_]:
    """Whether the step into each scan spans more than :data:`GAP_INTERVALS` of the
    odometry's usual intervals (:func:`usual_interval`), from its last message at or before the
    previous scan to its first at or after this one: a silence, or scans that far apart; shape
    (S,), the first scan's False."""
    gap = np.zeros(len(scans_ns), dtype=bool)
    if len(odometry_ns) < 2 or len(scans_ns) < 2:
        return gap
    usual = usual_interval(odometry_ns)
    before = np.searchsorted(odometry_ns, scans_ns[:-1], side="right") - 1
    after = np.minimum(np.searchsorted(odometry_ns, scans_ns[1:]), len(odometry_ns) - 1)
    span = odometry_ns[after] - odometry_ns[np.maximum(before, 0)]
    gap[1:] = span > GAP_INTERVALS * usual
    return gap


def usual_interval(stamps_ns: npt.NDArray[np.int64]) -> float:
    """The interval (ns) between messages that half the log's time is spent in, ``stamps_ns``
    (N,) sorted, N >= 2: the median of the intervals weighted by their length. A clock that
    stamps messages in bursts (several at nearly the same time, then a wait) has a median
    interval of almost nothing, so that every step would look like a gap; weighted by time, the
    wait between bursts is the usual interval, as it is the robot's real rate."""
    return half_share(np.diff(stamps_ns).astype(np.float64))


def half_share(lengths: FloatArray) -> float:
    """The length (of ``lengths`` (K,), K >= 1, none negative) that half their sum is made of:
    their median weighted by themselves."""
    ordered = np.sort(lengths)
    total = np.cumsum(ordered)
    return float(ordered[min(int(np.searchsorted(total, 0.5 * total[-1])), len(ordered) - 1)])


def typical_fit(fractions: FloatArray, floor: float) -> float:
    """The inlier fraction three quarters of the matches so far reached: how well this log's
    scans usually fit their local map. ``fractions`` (K,): every scan's so far; those under
    ``floor`` (fallbacks) and NaN are left out."""
    done = fractions[fractions >= floor]
    return float(np.percentile(done, 25)) if len(done) >= MIN_MATCHES else 1.0


class TypicalFit:
    """:func:`typical_fit` of the matches so far, kept one match at a time: a loop that asks
    it at every scan would otherwise sort the whole log's fits again each time (quadratic in
    the log's length). The same value, bit for bit: numpy's linear percentile on the sorted
    fits."""

    def __init__(self, floor: float) -> None:
        self.floor = floor
        self.done: list[float] = []

    def add(self, fraction: float) -> None:
        if fraction >= self.floor:  # False for NaN, as typical_fit leaves it out
            bisect.insort(self.done, fraction)

    def value(self) -> float:
        n = len(self.done)
        if n < MIN_MATCHES:
            return 1.0
        position = 0.25 * (n - 1)
        lo = math.floor(position)
        a, b = self.done[lo], self.done[min(lo + 1, n - 1)]
        t, d = position - lo, b - a
        return b - d * (1.0 - t) if t >= 0.5 else a + d * t


def relocate(
    local: MapToSearch,
    source: small_gicp.PointCloud,
    planar: FloatArray,
    guess: Pose,
    window_m: float,
    window_rad: float,
    params: Settings,
) -> Registration | None:
    """GICP of ``source`` (the scan, as the matcher gives it to GICP) from the best pose of its
    ``planar`` points (K, 2, robot frame) on the local map within ``window_m`` (capped at
    :data:`REACH_M`) and ``window_rad`` of ``guess``: the inlier fraction, pose and
    Hessian; None when no pose scores :data:`MIN_SCORE` or GICP leaves the window (in
    translation or heading)."""
    assert local.cloud is not None and local.tree is not None and local.tree2d is not None
    if local.grid is None:
        local.grid = LikelihoodGrid(np.asarray(local.tree2d.data), CELL_M, CELL_M, 4, REACH_M)
    window_m = min(window_m, REACH_M)
    reach = np.hypot(planar[:, 0], planar[:, 1])
    near = reach <= RANGE_M
    if not near.any():
        return None
    # a heading step that moves the farthest scored point by about a cell (Cartographer's rule)
    step_rad = CELL_M / max(float(reach[near].max()), CELL_M)
    found = search(local.grid, planar[near], guess, window_m, window_rad, step_rad, MIN_SCORE)
    if found is None:
        return None
    pose, hessian = register(
        local.cloud,
        local.tree,
        source,
        (found.x_m, found.y_m, found.theta_rad),
        params.correspondence_m,
        params.max_iterations,
    )
    # the window is what the odometry can have lost: GICP drifting out of it (a stale scan that
    # fits only turned further than a robot standing still can have turned) is no answer either
    if math.hypot(pose[0] - guess[0], pose[1] - guess[1]) > window_m + CELL_M:
        return None
    if abs(float(wrap_angle(pose[2] - guess[2]))) > window_rad + step_rad:
        return None
    return inlier_share(local.tree2d, planar, pose, params.inlier_m), pose, hessian


def inlier_share(tree: cKDTree, planar: FloatArray, pose: Pose, inlier_m: float) -> float:
    """The share of a scan's points (K, 2, robot frame) within ``inlier_m`` of the map points
    in ``tree`` when the scan is at ``pose``: the scan matcher's fit."""
    dist, _ = tree.query(placed_points(planar, pose), distance_upper_bound=inlier_m)
    return int(np.count_nonzero(np.isfinite(dist))) / len(dist)
