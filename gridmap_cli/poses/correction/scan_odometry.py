"""Motion from the laser alone: an odometry track made of the scans, for a log without odometry.

A hand-held laser or a simple platform records scans and nothing else. The scan matcher and the
pose graph (:mod:`.scan_match`, :mod:`.slam`) are seeded by odometry; here the scans give them
one. Each scan is registered (small_gicp's GICP, the scan as a thin vertical sheet, as the
matcher does) against a local map of the last few keyframe scans, starting from a
constant-velocity prediction: the last matched step, applied again. A prediction is only as
good as the motion is steady, so the match from where the last scan was (a stop) is tried too
and the better kept; when neither holds, the step scaled to the time since the last scan (a gap)
and turned headings, wider than the matcher's retries (a fast turn the velocity did not see
coming), until one does; a match that holds but fits worse than the log's scans usually do
(a wrong minimum: a late scan or a turn the prediction carried the wrong way) sends a
correlative search around the prediction, kept when it fits as well as usual. The track that
comes out is then the "odometry" the matcher and the graph consume, unchanged: they match every
scan again against their own local maps and close loops as they do with wheel odometry.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import small_gicp
from scipy.spatial import cKDTree

from gridmap_cli.geometry import compose, inverse, wrap_angle
from gridmap_cli.poses.correction.correlative import LikelihoodGrid
from gridmap_cli.poses.correction.degeneracy import keep_across, weak_axis
from gridmap_cli.poses.correction.relocate import TypicalFit, half_share, relocate
from gridmap_cli.poses.correction.scan_match import (
    Progress,
    ScanMatchParams,
    Scans,
    laser_scans,
)
from gridmap_cli.poses.correction.sheet_gicp import (
    placed_points,
    register,
    sheet_cloud,
)
from gridmap_cli.poses.sync import sensors_for_log
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import RobotDescription

FloatArray = npt.NDArray[np.float64]
Pose = tuple[float, float, float]

#: What a log's summary says when its motion came from the scans.
MOTION_NOTE = "no odometry: motion from the scans"


@dataclass(frozen=True)
class ScanOdometryParams:
    """How the scans are chained into a track. Metres, radians, seconds.

    ``downsample_m``: voxel of the scan and the local map; ``local_map_scans`` keyframes make
    the local map, a scan being one when the track moved ``keyframe_m`` or turned
    ``keyframe_rad`` since the last. ``correspondence_m``: GICP's largest correspondence
    distance. A match holds when ``min_inlier_fraction`` of the scan's points (at least
    ``min_points``) lie within ``inlier_m`` of the local map. ``heading_starts_rad``: the
    headings (offsets from the prediction) tried when a match does not hold.
    ``degenerate_ratio``: a match constrained in one direction only (a featureless corridor,
    :func:`.degeneracy.weak_axis`) keeps the prediction along it.
    ``max_gap_ratio``: the constant-velocity step is scaled by the time since the last scan
    over the last step's time, at most this much (a gap in the recording is not a long
    straight drive).
    ``search_m``: a match that holds but fits worse than the log's matches usually do
    (:class:`.relocate.TypicalFit`) may be a wrong minimum a wrong prediction led GICP into:
    the correlative search (:func:`.relocate.relocate`) looks this far and as far round as
    ``heading_starts_rad`` go around the prediction, and its match is kept when it fits as
    well as usual.
    """

    downsample_m: float = 0.1
    local_map_scans: int = 10
    keyframe_m: float = 0.2
    keyframe_rad: float = math.radians(5.0)
    correspondence_m: float = 1.0
    max_iterations: int = 30
    inlier_m: float = 0.15
    min_inlier_fraction: float = 0.5
    min_points: int = 20
    degenerate_ratio: float = 0.002
    max_gap_ratio: float = 3.0
    search_m: float = 0.5
    heading_starts_rad: tuple[float, ...] = tuple(
        math.radians(d) for d in (-15.0, 15.0, -30.0, 30.0, -45.0, 45.0, -60.0, 60.0)
    )


class _Keyframes:
    """The last keyframe scans, placed: GICP's target (3-D sheet) and a 2-D tree for scoring."""

    def __init__(self, params: ScanOdometryParams) -> None:
        self.params = params
        self.frames: deque[FloatArray] = deque(maxlen=params.local_map_scans)
        self.last: Pose | None = None
        self.cloud: small_gicp.PointCloud | None = None
        self.tree: small_gicp.KdTree | None = None
        self.tree2d: cKDTree | None = None
        self.grid: LikelihoodGrid | None = None

    def offer(self, points: FloatArray, pose: Pose) -> None:
        """Take the scan as a keyframe if the track moved or turned enough since the last."""
        if len(points) == 0:
            return
        if self.last is not None:
            moved = math.hypot(pose[0] - self.last[0], pose[1] - self.last[1])
            turned = abs(float(wrap_angle(pose[2] - self.last[2])))
            if moved < self.params.keyframe_m and turned < self.params.keyframe_rad:
                return
        self.frames.append(placed_points(points, pose))
        self.last = pose
        flat = np.vstack(list(self.frames))
        voxel = self.params.downsample_m
        self.cloud, self.tree = sheet_cloud(flat, voxel)
        self.tree2d = cKDTree(flat)
        self.grid = None

    def match(
        self, points: FloatArray, starts: list[Pose], bar: float
    ) -> tuple[Pose, float] | None:
        """The pose and inlier fraction of the best match from ``starts``, or None when none
        holds: the first two (the prediction and the last pose) are always tried, the others
        until one holds; one that fits under ``bar`` (the log's usual fit) is searched for
        around the prediction (``search_m``). Along a degenerate match's weak axis the pose
        is the first start's (the prediction): a corridor's walls say nothing of the motion
        along it."""
        p = self.params
        if self.cloud is None or self.tree is None or self.tree2d is None:
            return None
        source, _ = sheet_cloud(points, p.downsample_m)
        cloud = np.asarray(source.points())
        planar = cloud[np.abs(cloud[:, 2] - 0.5 * p.downsample_m) < 0.25 * p.downsample_m, :2]
        if len(planar) < p.min_points:
            return None
        best: tuple[float, Pose] | None = None
        for i, start in enumerate(starts):
            if i >= 2 and best is not None and best[0] >= p.min_inlier_fraction:
                break
            pose, hessian = register(
                self.cloud, self.tree, source, start, p.correspondence_m, p.max_iterations
            )
            dist, _ = self.tree2d.query(
                placed_points(planar, pose), distance_upper_bound=p.inlier_m
            )
            fraction = float(np.mean(np.isfinite(dist)))
            if fraction < p.min_inlier_fraction or (best is not None and fraction <= best[0]):
                continue
            axis = weak_axis(hessian, p.degenerate_ratio, pose[2])
            best = (fraction, pose if axis is None else keep_across(starts[0], pose, axis))
        if best is not None and best[0] < bar:
            # the correlative search around the prediction, as wide as the turned starts go
            window_rad = max(abs(d) for d in p.heading_starts_rad)
            found = relocate(self, source, planar, starts[0], p.search_m, window_rad, p)
            if found is not None and found[0] >= bar:
                axis = weak_axis(found[2], p.degenerate_ratio, found[1][2])
                best = (
                    found[0],
                    found[1] if axis is None else keep_across(starts[0], found[1], axis),
                )
        return None if best is None else (best[1], best[0])


def _moved(pose: FloatArray, step: Pose, ratio: float) -> Pose:
    """``pose`` (3,) moved on by ``ratio`` times ``step`` (in its own frame)."""
    x, y, th = compose(pose[0], pose[1], pose[2], *(ratio * v for v in step))
    return float(x), float(y), float(th)


def scan_odometry(
    scans: Scans, params: ScanOdometryParams | None = None, progress: Progress | None = None
) -> PoseTrack:
    """A track at the scans' stamps (shape (S,)) from the scans alone, starting at the origin:
    each scan matched from the constant-velocity prediction (see the module). A scan whose
    match does not hold keeps the prediction."""
    params = params or ScanOdometryParams()
    n = len(scans)
    poses = np.zeros((n, 3))
    keyframes = _Keyframes(params)
    fits = TypicalFit(params.min_inlier_fraction)
    t = scans.stamp_ns.astype(np.float64)
    for k in range(n):
        if k == 0:
            keyframes.offer(scans.points[0], (0.0, 0.0, 0.0))
            continue
        last: Pose = (float(poses[k - 1, 0]), float(poses[k - 1, 1]), float(poses[k - 1, 2]))
        guess, scaled = last, last
        if k >= 2:
            dx, dy, dth = compose(*inverse(*poses[k - 2]), *poses[k - 1])
            guess = _moved(poses[k - 1], (float(dx), float(dy), float(dth)), 1.0)
            if t[k - 1] > t[k - 2]:
                # a log's clock can run in bursts: the step as it was first, then as the time
                # since the last scan says
                ratio = min((t[k] - t[k - 1]) / (t[k - 1] - t[k - 2]), params.max_gap_ratio)
                scaled = _moved(poses[k - 1], (float(dx), float(dy), float(dth)), ratio)
        starts = [guess, last, scaled]
        starts += [(guess[0], guess[1], guess[2] + d) for d in params.heading_starts_rad]
        found = keyframes.match(scans.points[k], starts, fits.value())
        pose = guess if found is None else found[0]
        if found is not None:
            fits.add(found[1])
        poses[k] = pose
        keyframes.offer(scans.points[k], pose)
        if progress is not None:
            progress("motion from the scans", k + 1, n)
    return PoseTrack(
        stamp_ns=scans.stamp_ns.copy(),
        x_m=np.ascontiguousarray(poses[:, 0]),
        y_m=np.ascontiguousarray(poses[:, 1]),
        theta_rad=np.ascontiguousarray(wrap_angle(poses[:, 2])),
    )


def with_scan_motion(
    log: RangeLog,
    robot: RobotDescription | None,
    params: ScanOdometryParams | None = None,
    progress: Progress | None = None,
) -> RangeLog:
    """``log`` itself when it has odometry; else the log with the scans' track
    (:func:`scan_odometry`) as its odometry, for the scan matcher and the pose graph to
    correct. ``odometry_missing`` stays set: the track is no odometry to map with alone."""
    if log.odometry_missing is None or len(log.poses):
        return log
    scans = laser_scans(log, sensors_for_log(log, robot), ScanMatchParams())
    track = scan_odometry(scans, params, progress)
    return dataclasses.replace(log, poses=track)


def far_apart(track: PoseTrack, params: ScanOdometryParams | None = None) -> str | None:
    """What a track from the scans (:func:`scan_odometry`) cannot promise, or None: scans
    further apart than the inlier band (the step half the track's distance is driven in, so
    that stops do not count). A prediction off by a whole step then puts a scan outside the
    band, and in a corridor its walls fit as well wherever along it the scan is placed: the
    motion along it is the prediction's guess, and the free-space check cannot see a corridor
    shortened or stretched that the robot drove once."""
    band = (params or ScanOdometryParams()).inlier_m
    steps = np.hypot(np.diff(track.x_m), np.diff(track.y_m))
    if len(steps) == 0 or not steps.any():
        return None
    spacing = half_share(steps)
    if spacing <= band:
        return None
    return (
        f"no odometry, and the scans are {spacing:.2f} m apart, more than the scan matcher's "
        f"{band:g} m inlier band: along a corridor the scans alone may not tell how far the "
        "robot went between them; check the map"
    )
