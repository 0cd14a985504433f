"""Registrations that cannot see every direction: long, featureless corridors.

Between two parallel walls a scan match pins the robot across the corridor and in heading, and
says nothing along it: GICP's Hessian has one small eigenvalue, and the pose it returns slides
along the corridor by whatever its iterations happen to do. The scan matcher
(:mod:`.scan_match`) therefore keeps the odometry along that *weak axis*, and the pose graph
(:mod:`.slam`) gives the edges across such a stretch the odometry's uncertainty along it, so a
loop closure stretches or shrinks the corridor instead of bending the rest of the track.

- :func:`weak_axis`: the weak translation direction of a match, from its Hessian.
- :func:`keep_across`: a matched pose with its correction along the weak axis taken out.
- :func:`unchosen_slide`: a match that slid along its least constrained direction where the
  scan does not choose between the slide and the odometry's place: a corridor with a door or
  two is far from degenerate by its Hessian, and GICP from a retry's start can slide most of a
  step along it into a minimum that fits no better than where the odometry put the robot.
- :func:`weak_stretch`: how far a stretch of the track went along weak axes, and which way.
- :func:`second_ends`: the odometry's end of each step whose scan match and odometry disagree
  far beyond the log's usual, a second hypothesis for the pose graph (:mod:`.pose_graph`).
- :class:`DistanceScale`: the odometry's distance scale, learned from the steps that matched in
  every direction, so that "the odometry along the corridor" is the odometry with its scale
  error taken out (a Pioneer's uncalibrated distance is off by 1-2 %: a metre in a 60 m
  corridor). Without enough such steps it is 1.

Frames: small_gicp's Hessian is over a perturbation on the right of ``T_target_source``
(rotation, translation), so its translation block is in the *source* (robot) frame; the weak
axis is turned into the map frame by the matched heading.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from gridmap_cli.geometry import relative_poses
from gridmap_cli.poses.correction.sheet_gicp import placed_points

FloatArray = npt.NDArray[np.float64]

#: A step is doubted when its scan match misses the odometry by more than this many of the
#: log's typical misses, read as a Rayleigh sigma (the median of a Rayleigh variable is
#: 1.1774 sigma): a 2-D Gaussian miss passes 3 sigma once in 90 steps.
DOUBT_SIGMAS = 3.0
_RAYLEIGH_MEDIAN = math.sqrt(2.0 * math.log(2.0))


def weak_axis(hessian: FloatArray, ratio: float, theta_rad: float) -> FloatArray | None:
    """The unit vector (2,) in the map frame along which a match is unconstrained, or None.

    ``hessian`` (6, 6): small_gicp's, tangent (rotation, translation) in the robot frame;
    degenerate when the smaller eigenvalue of its x, y block is under ``ratio`` times the
    larger. ``theta_rad``: the matched heading (robot frame -> map frame).
    """
    if _clearly_constrained(hessian, ratio):
        return None
    values, vectors = np.linalg.eigh(hessian[3:5, 3:5])
    if values[1] > 0 and values[0] / values[1] >= ratio:
        return None
    return _in_map(vectors[:, 0], theta_rad)


def _least_axis(hessian: FloatArray, theta_rad: float) -> FloatArray:
    """The x, y block's least constrained direction, a unit vector (2,) in the map frame."""
    _, vectors = np.linalg.eigh(hessian[3:5, 3:5])
    return _in_map(vectors[:, 0], theta_rad)


def _in_map(u: FloatArray, theta_rad: float) -> FloatArray:
    """``u`` (2,), robot frame, turned into the map frame by the matched heading."""
    c, s = math.cos(theta_rad), math.sin(theta_rad)
    return np.array([c * u[0] - s * u[1], s * u[0] + c * u[1]])


def _clearly_constrained(hessian: FloatArray, ratio: float) -> bool:
    """Whether the x, y block's eigenvalues, in closed form, are so far from degenerate (twice
    ``ratio``, and clearly positive) that LAPACK's would say so too; most matches are, and
    the closed form costs a small fraction of ``eigh``'s call. Near the line ``eigh`` decides."""
    a, b, c = float(hessian[3, 3]), float(hessian[4, 3]), float(hessian[4, 4])
    mean, half = 0.5 * (a + c), math.hypot(0.5 * (a - c), b)
    top, bottom = mean + half, mean - half
    return bottom > 2.0 * ratio * top and bottom > 1e-6 * top


def keep_across(
    guess: tuple[float, float, float], pose: tuple[float, float, float], weak: FloatArray
) -> tuple[float, float, float]:
    """``pose`` with its correction from ``guess`` along ``weak`` (map frame) removed: the guess
    along the weak axis, the match across it and in heading."""
    shift = np.array([pose[0] - guess[0], pose[1] - guess[1]])
    across = shift - weak * float(weak @ shift)
    return guess[0] + float(across[0]), guess[1] + float(across[1]), pose[2]


def unchosen_slide(
    hessian: FloatArray,
    planar: FloatArray,
    pose: tuple[float, float, float],
    guess: tuple[float, float, float],
    local: cKDTree,
    inlier_m: float,
    step_m: float,
    came_from: tuple[float, float] | None = None,
) -> FloatArray | None:
    """The least constrained direction (unit vector (2,), map frame) of a match that moved the
    pose from the odometry's ``guess`` along it by more than ``inlier_m`` and either no more
    than the odometry's step (``step_m``) or so far that the robot's travel from ``came_from``
    (the previous scan's x, y; None: unknown) points against the odometry's, when the scan
    does not choose the move: of its ``planar``
    points (K, 2, robot frame), those within ``inlier_m`` of the ``local`` map's points at
    ``pose`` and not with the move taken back (:func:`keep_across`) do not outnumber those the
    other way round by twice their chance spread (a sign test: with no preference either way
    each such point falls either way at even odds, so the excess of n of them spreads by
    sqrt(n)). None otherwise: the scan chose the place, or the odometry's increment, shorter
    than the move and along it, is no place to go back to (a stop, or a clock that stamps in
    bursts); a move that turns the travel back is judged all the same, since which way wheels
    turned holds even where their stamps bunch.
    ``hessian`` (6, 6): small_gicp's, as :func:`weak_axis` reads it."""
    # most matches move less than the band in all: no eigenvectors for them
    if math.hypot(pose[0] - guess[0], pose[1] - guess[1]) <= inlier_m or len(planar) == 0:
        return None
    axis = _least_axis(hessian, pose[2])
    along = abs(float(axis @ np.array([pose[0] - guess[0], pose[1] - guess[1]])))
    if along <= inlier_m:
        return None
    if along > step_m:
        # past the odometry's step only where the match turns the robot's travel back against
        # the odometry's: wheels say which way they turned even where their stamps bunch
        if came_from is None:
            return None
        odo = np.array([guess[0] - came_from[0], guess[1] - came_from[1]])
        matched = np.array([pose[0] - came_from[0], pose[1] - came_from[1]])
        if float(odo @ matched) >= 0.0:
            return None
    at, _ = local.query(placed_points(planar, pose), distance_upper_bound=inlier_m)
    back, _ = local.query(
        placed_points(planar, keep_across(guess, pose, axis)), distance_upper_bound=inlier_m
    )
    moved_only = int(np.count_nonzero(np.isfinite(at) & ~np.isfinite(back)))
    back_only = int(np.count_nonzero(np.isfinite(back) & ~np.isfinite(at)))
    chosen = moved_only - back_only > 2.0 * math.sqrt(moved_only + back_only)
    return None if chosen else axis


@dataclass
class DistanceScale:
    """The odometry's distance scale: matched distance over odometry distance, summed over the
    steps that matched in every direction (each step's matched increment projected on the
    odometry's direction, both in the robot frame at the step's start). A ratio of sums, not a
    least-squares slope: the odometry's random distance error would bias a slope low.

    ``min_m``: odometry distance of such steps before the estimate is used (1 until then);
    ``max_error``: the estimate is clipped to 1 +- this (a scale further off is a matcher
    problem, not tyres). ``prior``: the scale used until then. :attr:`blind_m`: distance the
    matcher kept the odometry along weak axes before the estimate was used: where the prior's
    scale, not the learned one, went into the track.
    """

    min_m: float = 10.0
    max_error: float = 0.05
    prior: float = 1.0
    blind_m: float = 0.0
    _matched_m: float = 0.0
    _travel_m: float = 0.0

    def add(self, matched: tuple[float, float], odometry: tuple[float, float]) -> None:
        """One step that matched: its increments (metres, robot frame of the step's start)."""
        length = math.hypot(*odometry)
        if length <= 0:
            return
        self._matched_m += (matched[0] * odometry[0] + matched[1] * odometry[1]) / length
        self._travel_m += length

    def kept(self, odometry_m: float) -> None:
        """Distance kept from the odometry along a weak axis: counted while the estimate is not
        in use."""
        if not self.learned:
            self.blind_m += odometry_m

    @property
    def learned(self) -> bool:
        return self._travel_m >= self.min_m

    @property
    def factor(self) -> float:
        """The scale to multiply the odometry's increments by."""
        if not self.learned:
            return self.prior
        return min(
            1.0 + self.max_error, max(1.0 - self.max_error, self._matched_m / self._travel_m)
        )


def weak_stretch(
    poses: FloatArray, weak: FloatArray, start: int, end: int
) -> tuple[float, tuple[float, float]]:
    """Distance (m) the scans ``start + 1 .. end`` moved along their weak axes, and the mean
    axis as a unit vector in the frame of pose ``end``. ``poses`` (S, 3) and ``weak`` (S, 2),
    map frame, NaN where a scan matched in every direction."""
    axes = weak[start + 1 : end + 1]
    steps = np.diff(poses[start : end + 1, :2], axis=0)
    used = np.isfinite(axes[:, 0])
    if not used.any():
        return 0.0, (1.0, 0.0)
    axes, steps = axes[used], steps[used]
    along = np.einsum("ij,ij->i", axes, steps)
    distance = float(np.abs(along).sum())
    # the axis's sign is arbitrary: align each with the first before averaging
    signs = np.where(axes @ axes[0] < 0, -1.0, 1.0)
    mean = (axes * signs[:, None]).sum(axis=0)
    mean /= float(np.hypot(*mean)) or 1.0
    c, s = math.cos(poses[end, 2]), math.sin(poses[end, 2])
    return distance, (float(c * mean[0] + s * mean[1]), float(-s * mean[0] + c * mean[1]))


def second_ends(
    matched: FloatArray, odometry: FloatArray, nodes: npt.NDArray[np.intp], scale: float
) -> list[tuple[float, float] | None]:
    """For each step between consecutive ``nodes`` (indices into the scan-matched poses
    ``matched`` and the odometry ``odometry``, both (S, 3)): where the two disagree in
    translation by more than :data:`DOUBT_SIGMAS` times the log's own typical miss, the
    odometry's end of the step (x, y in the frame of the step's start, its distance times
    ``scale``, the odometry's learned scale); None elsewhere.

    Such a step is where a scan match may have slid (a corridor, a short-range laser that sees
    one wall) or the wheels slipped; which, only a loop closure can tell, so both ends are
    kept. Headings are the scan's: a scan's heading, from walls, is rarely what slides."""
    s, t = nodes[:-1], nodes[1:]
    scan = relative_poses(matched[s], matched[t])[:, :2]
    odo = scale * relative_poses(odometry[s], odometry[t])[:, :2]
    miss = np.hypot(*(scan - odo).T)
    # a log whose matches mostly are its odometry (scans that fell back) has no yardstick
    if len(miss) == 0 or not np.median(miss) > 0:
        return [None] * len(miss)
    bound = DOUBT_SIGMAS * float(np.median(miss)) / _RAYLEIGH_MEDIAN
    return [
        (float(o[0]), float(o[1])) if m > bound else None for m, o in zip(miss, odo, strict=True)
    ]
