"""A scan the odometry lost: found again on the local map by a correlative search.

The scan matcher starts GICP from the odometry's guess and from a few headings around it. Where
the odometry is off by more than that, none of those starts holds: a sparse log that turns 30
degrees between scans with a heading error of half of it, a log whose odometry messages stop
for a few seconds while the robot turns (the odometry then says it stood still). Keeping the
odometry's step there bends the whole map at that scan, and a loop closure can only straighten
it if the robot comes back.

The correlative search (:mod:`.correlative`, Cartographer's real-time correlative matcher in
spirit) scores every pose of a window around the guess on a likelihood grid of the local map:
the translation within the matcher's correction bound, the heading all round. GICP from the best
pose is judged by the scan matcher's own inlier test. A turn beyond what the odometry can be off
by is taken only when the scan fits as well as the log's scans usually do (:func:`typical_fit`):
a scan half in new space (the robot entering a room) fits some wrong heading about as well as
its own, and the search, maximising the overlap, finds that one.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
import numpy.typing as npt
import small_gicp
from scipy.spatial import cKDTree

from gridmap_cli.poses.correction.correlative import LikelihoodGrid, search
from gridmap_cli.poses.correction.planar import placed_points, planar_pose, pose_matrix

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
#: Matches needed before the log's usual fit is known; until then a turn beyond the odometry's
#: bound needs a perfect fit.
MIN_MATCHES = 10


class LocalMap(Protocol):
    """The scan matcher's local map: GICP's target and tree, the 2-D points' tree, and the
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
    @property
    def search_rad(self) -> float: ...


def typical_fit(fractions: FloatArray, floor: float) -> float:
    """The inlier fraction that three quarters of the matches so far reached: how well this
    log's scans usually fit their local map. ``fractions`` (K,): every scan's so far, those
    under ``floor`` (fallbacks) and NaN left out."""
    done = fractions[fractions >= floor]
    return float(np.percentile(done, 25)) if len(done) >= MIN_MATCHES else 1.0


def relocate(
    local: LocalMap,
    source: small_gicp.PointCloud,
    planar: FloatArray,
    guess: Pose,
    window_m: float,
    params: Settings,
) -> Registration | None:
    """GICP of ``source`` (the scan, as the matcher gives it to GICP) from the best pose of its
    ``planar`` points (K, 2, robot frame) on the local map within ``window_m`` (capped at
    :data:`REACH_M`) and ``params.search_rad`` of ``guess``: the inlier fraction, pose and
    Hessian; None when no pose scores :data:`MIN_SCORE` or GICP leaves the window."""
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
    found = search(
        local.grid, planar[near], guess, window_m, params.search_rad, step_rad, MIN_SCORE
    )
    if found is None:
        return None
    result = small_gicp.align(
        local.cloud,
        source,
        local.tree,
        init_T_target_source=pose_matrix(found.x_m, found.y_m, found.theta_rad),
        registration_type="GICP",
        max_correspondence_distance=params.correspondence_m,
        max_iterations=params.max_iterations,
        num_threads=1,
    )
    pose = planar_pose(np.asarray(result.T_target_source))
    if math.hypot(pose[0] - guess[0], pose[1] - guess[1]) > window_m + CELL_M:
        return None
    dist, _ = local.tree2d.query(placed_points(planar, pose), distance_upper_bound=params.inlier_m)
    return float(np.mean(np.isfinite(dist))), pose, np.asarray(result.H)
