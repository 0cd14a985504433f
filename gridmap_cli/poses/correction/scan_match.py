"""Scan matching: correct the odometry with the laser (scan to local map, no loop closure).

Each laser scan is registered against a local map made of the last few keyframe scans, starting
from the pose the odometry predicts (the previous corrected pose composed with the odometry's
increment since), with small_gicp's GICP: a planar scan becomes a thin vertical sheet (three
copies one voxel apart in z) so that GICP sees walls as planes, and x, y and yaw are kept.

A match is judged before it is trusted (``docs/scan-matching.md``):

- *poor*: too few points or inliers (within ``inlier_m`` of the local map), or a correction
  larger than the odometry can be wrong by: the scan is relocated (:mod:`.relocate`), or
  matched on the part of it the local map saw (*partial*, :mod:`.local_map`: a step into new
  space), or, failing both, the step keeps the odometry's increment (a *fallback*);
- *degenerate*: the translation is constrained in one direction only (a featureless corridor):
  the correction is kept across the corridor and the odometry is kept along it, its distance
  scale corrected by what the fully constrained steps measured (:mod:`.degeneracy`);
- *slid* along its least constrained direction by up to the odometry's step, where the scan does
  not choose the slide (:func:`.degeneracy.unchosen_slide`): the odometry is kept along it.

Frames: the corrected track is in the odometry frame, from the odometry's pose at the first
scan; poses between scans carry the odometry with the correction interpolated between scans.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import GridmapError
from gridmap_cli.geometry import compose, inverse, wrap_angle
from gridmap_cli.poses.correction.carry import carry
from gridmap_cli.poses.correction.degeneracy import (
    DistanceScale,
    keep_across,
    unchosen_slide,
    weak_axis,
)
from gridmap_cli.poses.correction.local_map import LocalMap, Tried, match_in_part
from gridmap_cli.poses.correction.relocate import (
    MOVED_M,
    inlier_share,
    odometry_gaps,
    relocate,
    typical_fit,
)
from gridmap_cli.poses.correction.sheet_gicp import (
    register,
    sheet_cloud,
)
from gridmap_cli.poses.sync import interpolate_pose, sensors_for_log
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import RangeSensor, RobotDescription

FloatArray = npt.NDArray[np.float64]
#: A caller's progress callback: (stage, done, total), e.g. ("scan matching", 120, 4000).
Progress = Callable[[str, int, int], object]

#: Per-scan outcome codes of :attr:`ScanMatch.status`.
MATCHED, FALLBACK, DEGENERATE, FIRST, PARTIAL = 0, 1, 2, 3, 4
STATUS_NAMES = {
    MATCHED: "matched", FALLBACK: "fallback", DEGENERATE: "degenerate", FIRST: "first",
    PARTIAL: "partial",
}  # fmt: skip


class NoLaserError(GridmapError):
    """The log holds no laser scan to match."""


@dataclass(frozen=True)
class ScanMatchParams:
    """How scans are matched. Metres and radians.

    ``max_range_m``: beams longer than this are left out of matching (far points are sparse and
    their angular error large). ``downsample_m``: voxel size for the scan and the local map.
    ``keyframe_m``/``keyframe_rad``: a scan joins the local map when the robot has moved this far
    or turned this much since the last one that did (a fallback only when it moved: turned in
    place, its guessed heading can be far off); ``local_map_scans`` keyframes are kept.
    ``correspondence_m``: GICP's maximum correspondence distance. ``fine_correspondence_m``:
    where the match leaves fewer of the scan's points within ``inlier_m`` of the local map than
    the odometry's guess did, GICP runs again from the guess with correspondences only this
    near, and the better fit is kept (0: never).
    ``inlier_m``: a matched point within this of the local map counts as an inlier;
    ``min_inlier_fraction`` of them are needed and at least ``min_points`` points.
    ``max_correction_m``/``max_correction_rad`` plus ``correction_per_m`` times the step length
    bound how far a match may move the odometry's guess. ``degenerate_ratio``: smallest over
    largest eigenvalue of the translation block of the match's Hessian below which the match is
    degenerate. ``heading_starts_rad``: extra starting headings (offsets from the guess) tried
    when the first match is poor.
    ``search_rad``: when no start holds, a correlative search finds GICP a start
    (:mod:`.relocate`), over this much heading either side of the guess at most (0: none).
    ``scale_min_m``/``scale_max_error``: the odometry's distance scale is learned from the
    straight (turning under ``scale_turn_rad``) matched steps once they cover this many metres,
    within 1 +- this (:class:`DistanceScale`); ``scale_min_m`` infinite keeps the odometry's own
    scale. When the matcher kept more than ``rescale_blind_m`` of odometry along weak axes before
    the scale was learned, the scans are matched again with the learned scale from the start.
    """

    max_range_m: float = 30.0
    downsample_m: float = 0.1
    keyframe_m: float = 0.3
    keyframe_rad: float = math.radians(10.0)
    local_map_scans: int = 20
    correspondence_m: float = 1.0
    fine_correspondence_m: float = 0.3
    max_iterations: int = 30
    inlier_m: float = 0.15
    min_inlier_fraction: float = 0.5
    min_points: int = 20
    max_correction_m: float = 0.5
    max_correction_rad: float = math.radians(15.0)
    correction_per_m: float = 0.5
    degenerate_ratio: float = 0.002
    scale_min_m: float = 10.0
    scale_max_error: float = 0.1
    rescale_blind_m: float = 5.0
    scale_turn_rad: float = math.radians(2.0)
    search_rad: float = math.pi
    heading_starts_rad: tuple[float, ...] = (
        math.radians(-8.0),
        math.radians(8.0),
        math.radians(-16.0),
        math.radians(16.0),
    )

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name == "heading_starts_rad":
                continue
            if not (value >= 0 and (math.isfinite(value) or f.name == "scale_min_m")):
                raise ValueError(f"{f.name} must be a finite number >= 0, got {value}")


@dataclass(frozen=True)
class Scans:
    """Laser scans: one per distinct stamp of the log's laser readings.

    ``stamp_ns`` shape (S,); ``points`` a list of S arrays, shape (K_i, 2), the beam end points
    (echoes only, within the matching range) in the robot base frame, metres."""

    stamp_ns: npt.NDArray[np.int64]
    points: list[FloatArray]

    def __len__(self) -> int:
        return int(self.stamp_ns.shape[0])


@dataclass(frozen=True)
class ScanMatch:
    """The corrected pose of every scan and how each was obtained, shape (S,) each.

    ``track``: corrected poses (odometry frame) at the scans' stamps. ``odometry``: the
    odometry's poses at the same stamps. ``status``: :data:`MATCHED`, :data:`FALLBACK`,
    :data:`DEGENERATE` or :data:`FIRST`. ``inlier_fraction``: share of the scan's points
    within ``inlier_m`` of the local map after the match (NaN for the first scan).
    ``weak_axis`` (S, 2): the unit vector (odometry frame) along which a degenerate match kept
    the odometry, NaN for the others; ``distance_scale``: the odometry's distance scale the
    matcher had learned by the last scan (1: none learned)."""

    track: PoseTrack
    odometry: PoseTrack
    status: npt.NDArray[np.int8]
    inlier_fraction: FloatArray
    seconds: float
    weak_axis: FloatArray | None = None
    distance_scale: float = 1.0

    @property
    def fallbacks(self) -> int:
        return int(np.count_nonzero(self.status == FALLBACK))

    @property
    def degenerate(self) -> int:
        return int(np.count_nonzero(self.status == DEGENERATE))

    def summary(self) -> dict[str, float | int]:
        """Counts for people and JSON: scans, matched, fallbacks, degenerate, the odometry's
        distance scale learned, seconds."""
        return {
            "scans": len(self.track),
            "matched": int(np.count_nonzero(self.status == MATCHED)),
            "partial": int(np.count_nonzero(self.status == PARTIAL)),
            "fallbacks": self.fallbacks,
            "degenerate": self.degenerate,
            "distance_scale": round(self.distance_scale, 4),
            "seconds": round(self.seconds, 3),
        }


def laser_scans(log: RangeLog, sensors: tuple[RangeSensor, ...], params: ScanMatchParams) -> Scans:
    """The log's laser readings grouped into scans by stamp (all lasers at one stamp together).

    ``sensors`` is the mounting of each of ``log.sensor_names``. Raises :class:`NoLaserError`
    when no sensor is a laser or no laser reading is in the log."""
    is_laser = np.array([s.kind == "laser" for s in sensors], dtype=bool)
    if not is_laser.any():
        kinds = sorted({s.kind for s in sensors}) or ["none"]
        raise NoLaserError(
            f"{log.source}: --pose scan-matched matches laser scans, and the log has no laser "
            f"(its range sensors: {', '.join(kinds)}); use --pose odometry or global"
        )
    r = log.readings
    keep = is_laser[r.sensor]
    table = np.array(
        [(s.x_m, s.y_m, s.yaw_rad, s.min_range_m, min(s.max_range_m, params.max_range_m))
         for s in sensors]
    ).reshape(len(sensors), 5)  # fmt: skip
    low, high = table[r.sensor, 3], table[r.sensor, 4]
    echo = keep & (r.range_m >= low) & (r.range_m < high)
    laser_stamps = np.unique(r.stamp_ns[keep])
    if len(laser_stamps) == 0:
        raise NoLaserError(f"{log.source}: the log holds no laser reading to match")
    idx = np.flatnonzero(echo)
    stamps = r.stamp_ns[idx]
    sx, sy, syaw = (table[r.sensor[idx], j] for j in range(3))
    rng = r.range_m[idx]
    px = sx + rng * np.cos(syaw)
    py = sy + rng * np.sin(syaw)
    # readings are time-ordered: each scan is a contiguous run of one stamp
    cuts = np.searchsorted(stamps, laser_stamps, side="left")
    ends = np.searchsorted(stamps, laser_stamps, side="right")
    points = [np.column_stack([px[a:b], py[a:b]]) for a, b in zip(cuts, ends, strict=True)]
    return Scans(stamp_ns=laser_stamps.astype(np.int64), points=points)


def match_scans(
    scans: Scans,
    odometry: PoseTrack,
    params: ScanMatchParams | None = None,
    progress: Progress | None = None,
) -> ScanMatch:
    """Register each scan against the local map, seeded by ``odometry`` (odometry frame).

    Scans outside the odometry's time span are an error (the caller keeps only those inside).
    ``progress`` is called after each scan with ``("scan matching", scans done, scans)``.
    """
    params = params or ScanMatchParams()
    started = time.perf_counter()
    ox, oy, oth, valid = interpolate_pose(odometry, scans.stamp_ns)
    if not valid.all():
        raise GridmapError("scan_match: scans outside the odometry's time span")
    odo = (ox, oy, oth)
    gap = odometry_gaps(odometry.stamp_ns, scans.stamp_ns)
    poses, status, score, weak, scale = _match_pass(scans, odo, params, 1.0, progress, gap)
    if scale.blind_m > params.rescale_blind_m and scale.factor != 1.0:
        # a corridor driven before the scale was known kept the odometry's own scale there, and
        # the rest of the track the learned one: a loop through both would not close. Again,
        # with the scale from the start (costs a second pass, only on such logs).
        poses, status, score, weak, scale = _match_pass(scans, odo, params, scale.factor, None, gap)
    track = PoseTrack(
        stamp_ns=scans.stamp_ns.copy(),
        x_m=np.ascontiguousarray(poses[:, 0]),
        y_m=np.ascontiguousarray(poses[:, 1]),
        theta_rad=np.ascontiguousarray(wrap_angle(poses[:, 2])),
    )
    odometry_track = PoseTrack(stamp_ns=scans.stamp_ns.copy(), x_m=ox, y_m=oy, theta_rad=oth)
    seconds = time.perf_counter() - started
    return ScanMatch(track, odometry_track, status, score, seconds, weak, scale.factor)


def _match_pass(
    scans: Scans,
    odometry: tuple[FloatArray, FloatArray, FloatArray],
    params: ScanMatchParams,
    prior_scale: float,
    progress: Progress | None,
    gap: npt.NDArray[np.bool_],
) -> tuple[FloatArray, npt.NDArray[np.int8], FloatArray, FloatArray, DistanceScale]:
    """One pass of :func:`match_scans`: poses (S, 3), status, inlier fractions, weak axes
    (S, 2) and the distance scale learned (``prior_scale`` until it is). ``gap`` (S,): the
    odometry has a gap before the scan (:func:`.relocate.odometry_gaps`)."""
    ox, oy, oth = odometry
    n = len(scans)
    poses = np.zeros((n, 3))
    status = np.full(n, MATCHED, dtype=np.int8)
    score = np.full(n, np.nan)
    weak = np.full((n, 2), np.nan)
    scale = DistanceScale(params.scale_min_m, params.scale_max_error, prior_scale)
    local = LocalMap(params)
    # the odometry's increment from each scan to the next, all at once
    steps = compose(*inverse(ox[:-1], oy[:-1], oth[:-1]), ox[1:], oy[1:], oth[1:])
    for k in range(n):
        pts = scans.points[k]
        if k == 0:
            poses[0] = ox[0], oy[0], oth[0]
            status[0] = FIRST
        else:
            # the odometry's increment since the last scan, applied to the last corrected pose
            dx, dy, dth = steps[0][k - 1], steps[1][k - 1], steps[2][k - 1]
            gx, gy, gth = compose(poses[k - 1, 0], poses[k - 1, 1], poses[k - 1, 2], dx, dy, dth)
            guess = (float(gx), float(gy), float(gth))
            # where the match keeps the odometry (along a corridor, or all of it on a fallback)
            # it keeps it with the learned distance scale; GICP itself starts from the
            # odometry's own guess, so a log that matches everywhere is not changed by it
            f = scale.factor
            sx, sy, _ = compose(
                poses[k - 1, 0], poses[k - 1, 1], poses[k - 1, 2], f * dx, f * dy, dth
            )
            scaled = (float(sx), float(sy), float(gth))
            step_m = float(math.hypot(dx, dy))
            poses[k], status[k], score[k], axis = _match_one(
                pts, guess, step_m, local, params, scaled,
                functools.partial(typical_fit, score[:k], params.min_inlier_fraction),
                params.search_rad if gap[k] else (
                    2.0 * params.max_correction_rad if step_m >= MOVED_M
                    else params.max_correction_rad
                ),
                (float(poses[k - 1, 0]), float(poses[k - 1, 1])),
            )  # fmt: skip
            if axis is not None:
                scale.kept(abs(float(axis @ (poses[k, :2] - poses[k - 1, :2]))))
                weak[k] = axis
            elif (
                status[k] == MATCHED
                and status[k - 1] in (MATCHED, FIRST)
                and abs(float(dth)) < params.scale_turn_rad
            ):
                # straight steps only: on a turn the odometry's distance is the arc, and its
                # rotation error moves the step sideways
                mx, my, _ = compose(*inverse(*poses[k - 1]), *poses[k])
                scale.add((float(mx), float(my)), (float(dx), float(dy)))
        if len(pts) and local.wants(tuple(poses[k]), status[k] == FALLBACK):
            local.add(pts, tuple(poses[k]))
        if progress is not None:
            progress("scan matching", k + 1, n)
    return poses, status, score, weak, scale


def _match_one(
    pts: FloatArray,
    guess: tuple[float, float, float],
    step_m: float,
    local: LocalMap,
    params: ScanMatchParams,
    kept: tuple[float, float, float] | None = None,
    typical: Callable[[], float] | None = None,
    window_rad: float = 0.0,
    came_from: tuple[float, float] | None = None,
) -> tuple[tuple[float, float, float], int, float, FloatArray | None]:
    """One scan's pose, status, inlier fraction and weak axis (map frame; None unless
    degenerate). GICP starts from ``guess``; ``kept`` (default ``guess``) is the pose a
    fallback takes and a degenerate match keeps along its weak axis. ``window_rad``: the
    heading window of the search for a lost scan (:mod:`.relocate`; at most ``search_rad``);
    ``typical``: the fit a relocation turned beyond the heading bound must reach
    (:func:`.relocate.typical_fit`; None: it never is); ``came_from``: the previous scan's
    x, y, for the slide rule (:func:`.degeneracy.unchosen_slide`)."""
    kept = kept or guess
    if local.cloud is None or local.tree is None or local.tree2d is None:
        return kept, FALLBACK, 0.0, None
    voxel = params.downsample_m
    source, _ = sheet_cloud(pts, voxel)
    cloud = np.asarray(source.points())
    planar = cloud[np.abs(cloud[:, 2] - 0.5 * voxel) < 0.25 * voxel, :2]
    if len(planar) < params.min_points:
        return kept, FALLBACK, 0.0, None
    limit_m = params.max_correction_m + params.correction_per_m * step_m
    best: tuple[float, tuple[float, float, float], FloatArray] | None = None
    # every registration within the bounds, with the share it needs: judged on what the local
    # map saw when none reaches its share of the whole scan
    tried: list[Tried] = []
    # the fit a registration turned beyond the heading bound needs; the same for every such one
    wide_fit = None if typical is None else functools.cache(typical)
    for offset in (0.0, *params.heading_starts_rad):
        start = (guess[0], guess[1], guess[2] + offset)
        pose, hessian = register(
            local.cloud, local.tree, source, start, params.correspondence_m, params.max_iterations
        )
        moved = math.hypot(pose[0] - guess[0], pose[1] - guess[1])
        turned = abs(float(wrap_angle(pose[2] - guess[2])))
        # beyond the heading bound (within the lost scan's window) only as a match in part,
        # and with the fit a relocation that turned as far needs
        wide = turned > params.max_correction_rad
        if moved > limit_m or (
            wide and (wide_fit is None or turned > min(window_rad, params.search_rad))
        ):
            continue
        fraction = inlier_share(local.tree2d, planar, pose, params.inlier_m)
        need = wide_fit() if wide and wide_fit is not None else params.min_inlier_fraction
        tried.append((fraction, pose, hessian, need))
        if wide:
            continue
        if best is None or fraction > best[0]:
            best = (fraction, pose, hessian)
        if fraction >= params.min_inlier_fraction:
            break
    fit = 0.0 if best is None else best[0]
    if params.fine_correspondence_m > 0 and (
        fit < inlier_share(local.tree2d, planar, guess, params.inlier_m)
    ):
        # GICP's far correspondences (the part of the scan the local map lacks, paired with
        # whatever lies within reach) pulled it off a pose that fits better: again from the
        # guess, with only the near ones
        pose, hessian = register(
            local.cloud, local.tree, source, guess, params.fine_correspondence_m,
            params.max_iterations,
        )  # fmt: skip
        moved = math.hypot(pose[0] - guess[0], pose[1] - guess[1])
        turned = abs(float(wrap_angle(pose[2] - guess[2])))
        if moved <= limit_m and turned <= params.max_correction_rad:
            fraction = inlier_share(local.tree2d, planar, pose, params.inlier_m)
            tried.append((fraction, pose, hessian, params.min_inlier_fraction))
            if best is None or fraction > best[0]:
                best = (fraction, pose, hessian)
    if (best is None or best[0] < params.min_inlier_fraction) and params.search_rad > 0:
        # no start held: the odometry may be off by more than the retries and the heading
        # bound allow (:mod:`.relocate`); beyond the bound only with the fit most of the
        # log's scans reach
        found = relocate(
            local, source, planar, guess, limit_m, min(window_rad, params.search_rad), params
        )
        if found is not None:
            wide = abs(float(wrap_angle(found[1][2] - guess[2]))) > params.max_correction_rad
            need = wide_fit() if wide and wide_fit is not None else params.min_inlier_fraction
            if not wide or wide_fit is not None:
                tried.append((*found, need))
                if (best is None or found[0] > best[0]) and (not wide or found[0] >= need):
                    best = found
    if best is None or best[0] < params.min_inlier_fraction:
        poor = 0.0 if best is None else best[0]
        best = match_in_part(tried, planar, local, params)
        if best is None:
            return kept, FALLBACK, poor, None
    fraction, pose, hessian = best
    matched = MATCHED if fraction >= params.min_inlier_fraction else PARTIAL
    axis = weak_axis(hessian, params.degenerate_ratio, pose[2])
    if axis is not None:
        return keep_across(kept, pose, axis), DEGENERATE, fraction, axis
    slid = unchosen_slide(
        hessian, planar, pose, kept, local.tree2d, params.inlier_m, step_m, came_from
    )
    return pose if slid is None else keep_across(kept, pose, slid), matched, fraction, None


def match_log(
    log: RangeLog,
    robot: RobotDescription | None,
    params: ScanMatchParams | None = None,
    progress: Progress | None = None,
) -> ScanMatch:
    """Match the laser scans of ``log`` that lie within its odometry's time span."""
    params = params or ScanMatchParams()
    return match_scans(log_scans(log, robot, params), log.poses, params, progress)


def log_scans(log: RangeLog, robot: RobotDescription | None, params: ScanMatchParams) -> Scans:
    """The laser scans of ``log`` that lie within its odometry's time span."""
    sensors = sensors_for_log(log, robot)
    scans = laser_scans(log, sensors, params)
    t = log.poses.stamp_ns
    inside = (scans.stamp_ns >= t[0]) & (scans.stamp_ns <= t[-1])
    if not inside.any():
        raise NoLaserError(
            f"{log.source}: no laser scan lies within the odometry's time span "
            "(recorded at different times?); scan matching needs both"
        )
    return Scans(
        stamp_ns=scans.stamp_ns[inside],
        points=[p for p, ok in zip(scans.points, inside, strict=True) if ok],
    )


def corrected_track(odometry: PoseTrack, match: ScanMatch) -> PoseTrack:
    """The odometry carried by the scans' corrections, at the odometry's and the scans' stamps.

    Between two scans the odometry is carried from both and the two blended by the share of the
    odometry's motion done (:func:`.carry.carry`); before the first and after the last scan the
    nearest one carries it. So the track keeps the odometry's own shape between scans and passes
    through every corrected scan pose.
    """
    stamps = np.union1d(odometry.stamp_ns, match.track.stamp_ns).astype(np.int64)
    ox, oy, oth, _ = interpolate_pose(odometry, stamps)
    m, o = match.track, match.odometry
    x, y, th = carry(
        stamps, (ox, oy, oth), m.stamp_ns, (o.x_m, o.y_m, o.theta_rad), (m.x_m, m.y_m, m.theta_rad)
    )
    return PoseTrack(stamp_ns=stamps, x_m=x, y_m=y, theta_rad=th)


def scan_matched_log(
    log: RangeLog,
    robot: RobotDescription | None,
    params: ScanMatchParams | None = None,
    progress: Progress | None = None,
) -> tuple[RangeLog, ScanMatch]:
    """``log`` with its poses replaced by the scan-matched track, and the match itself."""
    match = match_log(log, robot, params, progress)
    return dataclasses.replace(log, poses=corrected_track(log.poses, match)), match
