"""The scan matcher's local map: the last few keyframe scans, placed in the odometry frame.

GICP registers each scan against them as a thin vertical sheet (:mod:`.planar`); the inlier
test scores a match on their 2-D points; a lost scan is searched for on a likelihood grid of
them (:mod:`.relocate`), built only when a scan first needs it.
"""

from __future__ import annotations

import math
from collections import deque
from typing import TYPE_CHECKING, Protocol

import numpy as np
import numpy.typing as npt
import small_gicp
from scipy.spatial import cKDTree

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.poses.correction.planar import planar_sheet

if TYPE_CHECKING:
    from gridmap_cli.poses.correction.correlative import LikelihoodGrid

FloatArray = npt.NDArray[np.float64]


class KeyframeSettings(Protocol):
    """What the local map takes from the scan matcher's settings (:class:`.ScanMatchParams`)."""

    @property
    def local_map_scans(self) -> int: ...
    @property
    def keyframe_m(self) -> float: ...
    @property
    def keyframe_rad(self) -> float: ...
    @property
    def downsample_m(self) -> float: ...


class LocalMap:
    """The last keyframe scans in the odometry frame, for GICP (3D sheet) and scoring (2D)."""

    def __init__(self, params: KeyframeSettings) -> None:
        self.params = params
        self.frames: deque[FloatArray] = deque(maxlen=params.local_map_scans)
        self.last_pose: tuple[float, float, float] | None = None
        self.cloud: small_gicp.PointCloud | None = None
        self.tree: small_gicp.KdTree | None = None
        self.tree2d: cKDTree | None = None
        self.grid: LikelihoodGrid | None = None  # built when a poor match first needs it

    def wants(self, pose: tuple[float, float, float], fallback: bool = False) -> bool:
        if self.last_pose is None:
            return True
        dx, dy = pose[0] - self.last_pose[0], pose[1] - self.last_pose[1]
        turn = 0.0 if fallback else abs(float(wrap_angle(pose[2] - self.last_pose[2])))
        return math.hypot(dx, dy) >= self.params.keyframe_m or turn >= self.params.keyframe_rad

    def add(self, world_points: FloatArray, pose: tuple[float, float, float]) -> None:
        self.frames.append(world_points)
        self.last_pose = pose
        flat = np.vstack(list(self.frames))
        voxel = self.params.downsample_m
        self.cloud, self.tree = small_gicp.preprocess_points(
            planar_sheet(flat, voxel), downsampling_resolution=voxel, num_neighbors=10
        )
        # unbalanced: quicker to build, as quick to query, and the same nearest points
        self.tree2d = cKDTree(flat, balanced_tree=False)
        self.grid = None
