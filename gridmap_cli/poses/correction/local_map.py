"""The scan matcher's local map, and a scan matched on the part of it the map saw.

The local map is the last keyframe scans in the odometry frame, kept three ways: as a thin sheet
for GICP, as planar points for scoring a match, and as seen from their poses (``views``), which
tells the points of a new scan that lie where the map's beams reached from those that lie
beyond anything it saw.

**A scan a long step into new space** (a fast robot, a sparse log, a corner, a doorway) has
its new part unmatched whatever its pose: under the inlier gate over the whole scan, it would
keep the odometry's step, and with it the odometry's turn (on a log a metre between scans, off
by 5-15 degrees at a time, which no later scan takes back). So a match under the gate is judged
as a loop closure overlapping in part is (:mod:`.overlap`): on the points the map saw, which must
reach the gate's share, and put no more than the free-space check's floor of them in the space
the map's beams crossed (:func:`.overlap.seen_and_holding`). Its unseen points still pulled GICP
towards whatever lay within the correspondence distance, so the pose is then taken from the
seen points alone.

A part is less evidence than a whole. Where the truth lies beyond the matcher's correction bound
(a wheel that slipped a metre), some pose within it may still fit the seen part, and one start
of GICP finds it; the other starts end elsewhere, each on its own fit. So a match in part also
needs a second start (of the matcher's headings, or the relocation) that ended on the same pose,
the scan placed by the two within the inlier band on average: a minimum GICP falls into from
more than one side.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Protocol

import numpy as np
import numpy.typing as npt
import small_gicp
from scipy.spatial import cKDTree

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.poses.correction.correlative import LikelihoodGrid
from gridmap_cli.poses.correction.overlap import seen_and_holding
from gridmap_cli.poses.correction.sheet_gicp import (
    placed_points,
    register,
    sheet_cloud,
)

FloatArray = npt.NDArray[np.float64]
Pose = tuple[float, float, float]
#: A registration tried on the local map: (inlier fraction, pose, Hessian (6, 6), the inlier
#: share it needs).
Tried = tuple[float, Pose, FloatArray, float]


class Keyframing(Protocol):
    """What the local map takes from the scan matcher's settings."""

    @property
    def keyframe_m(self) -> float: ...
    @property
    def keyframe_rad(self) -> float: ...
    @property
    def local_map_scans(self) -> int: ...
    @property
    def downsample_m(self) -> float: ...


class Settings(Keyframing, Protocol):
    """What a match in part takes from the scan matcher's settings."""

    @property
    def inlier_m(self) -> float: ...
    @property
    def min_points(self) -> int: ...
    @property
    def max_iterations(self) -> int: ...


class LocalMap:
    """The last ``local_map_scans`` keyframe scans in the odometry frame, for GICP (3D sheet),
    scoring (2D) and their views (pose, points in the robot frame)."""

    def __init__(self, params: Keyframing) -> None:
        self.params = params
        self.frames: deque[FloatArray] = deque(maxlen=params.local_map_scans)
        self.views: deque[tuple[Pose, FloatArray]] = deque(maxlen=params.local_map_scans)
        self.last_pose: Pose | None = None
        self.cloud: small_gicp.PointCloud | None = None
        self.tree: small_gicp.KdTree | None = None
        self.tree2d: cKDTree | None = None
        self.grid: LikelihoodGrid | None = None  # built when a poor match first needs it

    def wants(self, pose: Pose, fallback: bool = False) -> bool:
        """Whether a scan at ``pose`` joins: the robot moved ``keyframe_m`` or turned
        ``keyframe_rad`` since the last keyframe (a fallback only when it moved)."""
        if self.last_pose is None:
            return True
        dx, dy = pose[0] - self.last_pose[0], pose[1] - self.last_pose[1]
        turn = 0.0 if fallback else abs(float(wrap_angle(pose[2] - self.last_pose[2])))
        return math.hypot(dx, dy) >= self.params.keyframe_m or turn >= self.params.keyframe_rad

    def add(self, points: FloatArray, pose: Pose) -> None:
        """A keyframe: ``points`` (K, 2) in the robot frame, at ``pose`` (odometry frame)."""
        self.frames.append(placed_points(points, pose))
        self.views.append((pose, points))
        self.last_pose = pose
        flat = np.vstack(list(self.frames))
        voxel = self.params.downsample_m
        self.cloud, self.tree = sheet_cloud(flat, voxel)
        # unbalanced: quicker to build, as quick to query, and the same nearest points
        self.tree2d = cKDTree(flat, balanced_tree=False)
        self.grid = None


def match_in_part(
    tried: list[Tried], planar: FloatArray, local: LocalMap, params: Settings
) -> tuple[float, Pose, FloatArray] | None:
    """The first of ``tried`` (best inlier fraction first) whose scan ``planar`` (K, 2, robot
    frame) holds on what ``local`` saw, registered again on those points alone: its fraction
    over the whole scan, pose and Hessian; None where none holds (see the module)."""
    assert local.cloud is not None and local.tree is not None and local.tree2d is not None
    target = (np.array([p for p, _ in local.views]), [points for _, points in local.views])
    placed = [placed_points(planar, t[1]) for t in tried]
    for fraction, pose, _, share in sorted(tried, key=lambda t: -t[0]):
        moved = placed_points(planar, pose)
        # one start's answer alone may be any of several poses the seen part fits about as well
        agree = sum(float(np.mean(np.hypot(*(p - moved).T))) <= params.inlier_m for p in placed)
        if agree < 2:
            continue
        dist, _ = local.tree2d.query(moved, distance_upper_bound=params.inlier_m)
        seen = seen_and_holding(
            moved, np.isfinite(dist), target, share, params.inlier_m, params.min_points
        )
        if seen is None:
            continue
        source, _ = sheet_cloud(planar[seen], params.downsample_m)
        pose, hessian = register(
            local.cloud, local.tree, source, pose, params.inlier_m, params.max_iterations
        )
        return fraction, pose, hessian
    return None
