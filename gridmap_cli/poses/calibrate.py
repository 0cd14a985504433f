"""Estimate the odometry-error coefficients (f, g) from a log that carries ground truth.

The log is cut into consecutive windows of travel: a window ends as soon as the robot has driven
``window_m`` metres or turned ``window_rad`` radians (both measured on the truth) since it began.
Over each window the odometry's motion is compared with the truth's through what no frame changes
(the length of the window's displacement, the sum of its turns), so the error a window shows is the
error made within it, whatever the drift before it:

* distance error ``e_d = |odometry displacement| - |true displacement|`` (metres);
* heading error ``e_h = odometry rotation - true rotation`` (radians, signed sums of the wrapped
  heading increments, so a window may turn more than pi).

Systematic terms are least-squares fits through the origin, signed:
``e_d = scale * |true displacement|`` and ``e_h = turn_scale * true rotation + drift * driven``
(both heading terms fitted together). Random-walk terms come from what is left: its variance
grows with what was driven (turned), so ``sigma_d**2 = sum(r_d**2) / sum(driven)`` and
``sigma_h**2 = sum(r_h**2) / sum(|turned|)``, the weighted least-squares fits of the squared
residuals, non-negative by construction. The file gets the magnitudes: a spread has no sign.

A term the log cannot show (no rotation in a straight-line log) is reported as not estimated
and written as 0. Frames do not matter, so the odometry may start anywhere.

**A reference is not truth.** A SLAM-corrected track (CARMEN's corrected poses, ``/amcl_pose``)
jitters: each of its poses is off by some error that does not grow with travel. A window's error
then holds that jitter twice (at its start and at its end), whatever its length, while the
odometry's random walk grows with the window. So the windows are cut again at
:data:`JITTER_LADDER` times the window (1, 2, 5 and 10 m by default), and the squared residuals of
all of them are fitted as ``r**2 = J + s**2 * x`` (x the metres driven, or the radians turned):
the slope ``s**2`` is the odometry's random walk, the intercept ``J = 2 j**2`` the reference's
jitter ``j`` per pose, which is reported, not written. Both are kept >= 0. The fit is made on
the whole log and on each half of it (by distance driven), so the spread of every coefficient
between the halves shows how far it can be trusted.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import GridmapError
from gridmap_cli.geometry import wrap_angle
from gridmap_cli.poses.odometry_error import DEFAULT_SONAR_RELATIVE_ERROR, OdometryError, travelled
from gridmap_cli.poses.sync import interpolate_pose
from gridmap_cli.records import PoseTrack, RangeLog

FloatArray = npt.NDArray[np.float64]

DEFAULT_WINDOW_M = 1.0
DEFAULT_WINDOW_RAD = math.pi / 2
#: A window's budget counts as used up within this much (metres or radians) of it.
BUDGET_TOLERANCE = 1e-9
#: Fewer complete windows than this cannot separate a systematic error from a random one.
MIN_WINDOWS = 3
#: Turning less than this in all (truth) leaves the turn terms unestimated: a quarter turn.
MIN_ROTATION_RAD = math.pi / 2
#: The window lengths (multiples of the window and its turn budget) whose residuals separate the
#: reference's jitter (the same at every length) from the odometry's random walk (growing).
JITTER_LADDER = (0.5, 1.0, 2.0, 5.0)


class CalibrationError(GridmapError):
    """The log cannot be calibrated on: too little travel."""


@dataclass(frozen=True)
class Windows:
    """Per-window comparison of odometry and truth, shape (W,) each, and the windows' budgets.

    ``driven_m``, ``turned_rad``: true path length and signed true rotation in the window;
    ``displacement_m``: length of the true relative translation; ``distance_error_m`` and
    ``heading_error_rad``: odometry minus truth (see module docstring). ``window_m`` and
    ``window_rad``: the distance and turn that close a window.
    """

    driven_m: FloatArray
    turned_rad: FloatArray
    displacement_m: FloatArray
    distance_error_m: FloatArray
    heading_error_rad: FloatArray
    window_m: float
    window_rad: float

    def __len__(self) -> int:
        return int(self.driven_m.shape[0])


@dataclass(frozen=True)
class Calibration:
    """What :func:`calibrate` found.

    ``model``: the coefficients to write (magnitudes). Signed estimates: ``scale_error`` (0.02:
    odometry reports 1.02 m per true metre), ``turn_scale_error`` (per true radian),
    ``heading_drift_rad_per_m`` (positive: counter-clockwise). ``*_estimated`` say whether the
    log could show the term at all. Residuals are the root mean square per window after the
    systematic terms are taken out.
    """

    model: OdometryError
    scale_error: float
    turn_scale_error: float
    heading_drift_rad_per_m: float
    distance_estimated: bool
    turn_estimated: bool
    drift_estimated: bool
    windows: int
    driving_windows: int
    driven_m: float
    turned_rad: float
    distance_residual_m: float
    heading_residual_rad: float
    window_m: float
    window_rad: float
    jitter_m: float = 0.0
    jitter_rad: float = 0.0
    jitter_estimated: bool = False
    halves: tuple[OdometryError, OdometryError] | None = None

    @property
    def turning_windows(self) -> int:
        """Windows closed by their turn budget: all those that did not drive theirs."""
        return self.windows - self.driving_windows

    def as_dict(self) -> dict[str, object]:
        return {
            "coefficients": self.model.as_dict(),
            "signed": {
                "scale_error": self.scale_error,
                "turn_scale_error": self.turn_scale_error,
                "heading_drift_rad_per_m": self.heading_drift_rad_per_m,
            },
            "estimated": {
                "distance": self.distance_estimated,
                "turn": self.turn_estimated,
                "heading_drift": self.drift_estimated,
            },
            "windows": {
                "total": self.windows,
                "driving": self.driving_windows,
                "turning": self.turning_windows,
                "window_m": self.window_m,
                "window_rad": self.window_rad,
            },
            "travel": {"driven_m": self.driven_m, "turned_rad": self.turned_rad},
            "residual": {
                "distance_m": self.distance_residual_m,
                "heading_rad": self.heading_residual_rad,
            },
            "reference_jitter": {
                "estimated": self.jitter_estimated,
                "position_m": self.jitter_m,
                "heading_rad": self.jitter_rad,
            },
            "halves": [h.as_dict() for h in self.halves] if self.halves else None,
        }


def truth_at_odometry(log: RangeLog) -> tuple[PoseTrack, PoseTrack]:
    """Odometry and truth at the same stamps (the odometry's, within the truth's span).

    Raises :class:`~gridmap_cli.errors.InputFileError` for a log without ground truth.
    """
    odo, truth = log.poses, log.require_truth("calibrate compares the odometry against it")
    if np.array_equal(odo.stamp_ns, truth.stamp_ns):
        return odo, truth
    x, y, th, valid = interpolate_pose(truth, odo.stamp_ns)
    keep = valid
    return (
        PoseTrack(odo.stamp_ns[keep], odo.x_m[keep], odo.y_m[keep], odo.theta_rad[keep]),
        PoseTrack(odo.stamp_ns[keep], x[keep], y[keep], th[keep]),
    )


def compare_windows(
    odometry: PoseTrack,
    truth: PoseTrack,
    window_m: float = DEFAULT_WINDOW_M,
    window_rad: float = DEFAULT_WINDOW_RAD,
) -> Windows:
    """Cut the tracks (same stamps, shape (N,)) into windows of travel and compare them.

    Only complete windows are returned: the travel left over at the end is dropped.
    """
    if not (window_m > 0.0 and math.isfinite(window_m)):
        raise ValueError(f"window must be a positive number of metres, got {window_m}")
    if not (window_rad > 0.0 and math.isfinite(window_rad)):
        raise ValueError(f"window turn must be a positive number of radians, got {window_rad}")
    dist, rot = travelled(truth)
    # the heading error needs the signed rotation, which travelled() does not keep
    signed_true = np.concatenate([[0.0], np.cumsum(wrap_angle(np.diff(truth.theta_rad)))])
    signed_odo = np.concatenate([[0.0], np.cumsum(wrap_angle(np.diff(odometry.theta_rad)))])
    starts: list[int] = []
    ends: list[int] = []
    i = 0
    n = dist.shape[0]
    while i < n - 1:
        # first pose at which either budget is used up, to within rounding: a 90-degree corner
        # must close a 90-degree window whether its increments sum to pi/2 or to 1 ulp less
        # (the same run read from CSV and from ROS 2 quaternions differs by that much)
        j_d = int(np.searchsorted(dist, dist[i] + window_m - BUDGET_TOLERANCE, side="left"))
        j_r = int(np.searchsorted(rot, rot[i] + window_rad - BUDGET_TOLERANCE, side="left"))
        j = min(j_d, j_r)
        if j >= n:
            break
        starts.append(i)
        ends.append(j)
        i = j
    s = np.asarray(starts, dtype=np.int64)
    e = np.asarray(ends, dtype=np.int64)
    # a length is the same in every frame: no need to move each window into its start frame
    true_disp = np.hypot(truth.x_m[e] - truth.x_m[s], truth.y_m[e] - truth.y_m[s])
    odo_disp = np.hypot(odometry.x_m[e] - odometry.x_m[s], odometry.y_m[e] - odometry.y_m[s])
    return Windows(
        driven_m=dist[e] - dist[s],
        turned_rad=signed_true[e] - signed_true[s],
        displacement_m=true_disp,
        distance_error_m=odo_disp - true_disp,
        heading_error_rad=(signed_odo[e] - signed_odo[s]) - (signed_true[e] - signed_true[s]),
        window_m=window_m,
        window_rad=window_rad,
    )


def fit(
    windows: Windows,
    sonar_relative_error: float = DEFAULT_SONAR_RELATIVE_ERROR,
    ladder: Sequence[Windows] = (),
) -> Calibration:
    """Fit the coefficients to compared windows (module docstring gives the estimators).

    ``ladder``: the same tracks cut into windows of other lengths. With two lengths or more
    (``windows`` counts as one), the random-walk terms come from the fit of the squared
    residuals of all of them with an intercept, the reference's jitter; otherwise from
    ``windows`` alone, with no jitter.
    """
    full_m = windows.window_m - BUDGET_TOLERANCE  # a window's distance budget, used up
    driven = windows.driven_m
    turned = windows.turned_rad
    disp = windows.displacement_m
    total_driven = float(driven.sum())
    total_turned = float(np.abs(turned).sum())

    distance_ok = bool(float(np.sum(disp**2)) > 0.0 and total_driven >= full_m)
    scale = float(np.sum(windows.distance_error_m * disp) / np.sum(disp**2)) if distance_ok else 0.0
    r_d = windows.distance_error_m - scale * disp

    turn_ok = total_turned >= MIN_ROTATION_RAD
    drift_ok = total_driven >= full_m
    turn_scale, drift = 0.0, 0.0
    r_h = windows.heading_error_rad
    if turn_ok or drift_ok:
        design = _heading_design(windows, turn_ok, drift_ok)
        solution, *_ = np.linalg.lstsq(design, windows.heading_error_rad, rcond=None)
        r_h = windows.heading_error_rad - design @ solution
        # the turn column comes first, the drift column last, each only when estimated
        turn_scale = float(solution[0]) if turn_ok else 0.0
        drift = float(solution[-1]) if drift_ok else 0.0

    rungs = [windows, *(w for w in ladder if w.window_m != windows.window_m)]
    jitter_ok = len(rungs) >= 2
    if jitter_ok:
        # every rung's residuals under the systematic terms fitted on the main windows
        x_d = np.concatenate([w.driven_m for w in rungs])
        y_d = np.concatenate([(w.distance_error_m - scale * w.displacement_m) ** 2 for w in rungs])
        x_h = np.concatenate([np.abs(w.turned_rad) for w in rungs])
        y_h = np.concatenate(
            [
                (w.heading_error_rad - turn_scale * w.turned_rad - drift * w.driven_m) ** 2
                for w in rungs
            ]
        )
        jit_d, var_d = intercept_slope(x_d, y_d)
        jit_h, var_h = intercept_slope(x_h, y_h)
        sigma_d = math.sqrt(var_d) if distance_ok else 0.0
        sigma_h = math.sqrt(var_h) if turn_ok else 0.0
        jitter_m = math.sqrt(jit_d / 2.0) if distance_ok else 0.0
        jitter_rad = math.sqrt(jit_h / 2.0)
    else:
        sigma_d = math.sqrt(float(np.sum(r_d**2)) / total_driven) if distance_ok else 0.0
        sigma_h = math.sqrt(float(np.sum(r_h**2)) / total_turned) if turn_ok else 0.0
        jitter_m = jitter_rad = 0.0

    # rounding noise of an error-free log (1e-17) is no error: write it as 0
    scale, sigma_d, sigma_h = _clean(scale), _clean(sigma_d), _clean(sigma_h)
    turn_scale, drift = _clean(turn_scale), _clean(drift)
    model = OdometryError(
        range_m_per_m=abs(scale),
        range_m_per_sqrt_m=sigma_d,
        bearing_rad_per_rad=abs(turn_scale),
        bearing_rad_per_sqrt_rad=sigma_h,
        heading_drift_rad_per_m=abs(drift),
        sonar_relative_error=sonar_relative_error,
    )
    return Calibration(
        model=model,
        scale_error=scale,
        turn_scale_error=turn_scale,
        heading_drift_rad_per_m=drift,
        distance_estimated=distance_ok,
        turn_estimated=turn_ok,
        drift_estimated=drift_ok,
        windows=len(windows),
        # a window "drives" when it ended on its distance budget, "turns" otherwise
        driving_windows=int(np.count_nonzero(driven >= full_m)),
        driven_m=total_driven,
        turned_rad=total_turned,
        distance_residual_m=float(np.sqrt(np.mean(r_d**2))),
        heading_residual_rad=float(np.sqrt(np.mean(r_h**2))),
        window_m=windows.window_m,
        window_rad=windows.window_rad,
        jitter_m=_clean(jitter_m),
        jitter_rad=_clean(jitter_rad),
        jitter_estimated=jitter_ok,
    )


def _heading_design(windows: Windows, turn_ok: bool, drift_ok: bool) -> FloatArray:
    columns = [c for c, ok in ((windows.turned_rad, turn_ok), (windows.driven_m, drift_ok)) if ok]
    return np.column_stack(columns)


def intercept_slope(x: FloatArray, y: FloatArray) -> tuple[float, float]:
    """Least-squares ``y = a + b x`` over windows (shape (W,)) with ``a, b >= 0``: the squared
    residual's constant part (the reference's jitter, twice) and its growth with travel (the
    odometry's random walk). A negative one is set to 0 and the other refitted alone."""
    if y.size == 0:
        return 0.0, 0.0
    design = np.column_stack([np.ones_like(x), x])
    (a, b), *_ = np.linalg.lstsq(design, y, rcond=None)
    if a >= 0.0 and b >= 0.0:
        return float(a), float(b)
    sxx = float(np.sum(x * x))
    slope_only = float(np.sum(x * y)) / sxx if sxx > 0.0 else 0.0
    if b < 0.0 or slope_only <= 0.0:
        return max(float(np.mean(y)), 0.0), 0.0
    return 0.0, slope_only


def _clean(x: float) -> float:
    return 0.0 if abs(x) < 1e-12 else float(x)


def calibrate(
    log: RangeLog,
    window_m: float = DEFAULT_WINDOW_M,
    window_rad: float = DEFAULT_WINDOW_RAD,
    sonar_relative_error: float = DEFAULT_SONAR_RELATIVE_ERROR,
) -> Calibration:
    """Estimate f and g from ``log``'s odometry against its ground truth (or reference track),
    with the reference's jitter and the coefficients of each half of the log.

    Raises :class:`~gridmap_cli.errors.InputFileError` for a log without truth and
    :class:`CalibrationError` for one with fewer than :data:`MIN_WINDOWS` complete windows of
    travel.
    """
    odometry, truth = truth_at_odometry(log)
    whole = calibrate_tracks(odometry, truth, window_m, window_rad, sonar_relative_error)
    if whole is None:
        dist, rot = travelled(truth)
        # a truth that never overlaps the odometry is empty: it drives nothing
        driven, turned = (float(dist[-1]), float(rot[-1])) if len(truth) else (0.0, 0.0)
        n = len(compare_windows(odometry, truth, window_m, window_rad)) if len(truth) else 0
        raise CalibrationError(
            f"{log.source}: too little travel to calibrate: the truth drives "
            f"{driven:.2f} m and turns {math.degrees(turned):.0f} deg, "
            f"{n} complete window{'s' if n != 1 else ''} of "
            f"{window_m:g} m or {math.degrees(window_rad):g} deg; need at least {MIN_WINDOWS}"
        )
    dist, _ = travelled(truth)
    cut = int(np.searchsorted(dist, 0.5 * dist[-1]))
    halves = [
        calibrate_tracks(o, t, window_m, window_rad, sonar_relative_error)
        for o, t in ((_part(odometry, 0, cut + 1), _part(truth, 0, cut + 1)),
                     (_part(odometry, cut, None), _part(truth, cut, None)))
    ]  # fmt: skip
    h0, h1 = halves
    if h0 is not None and h1 is not None:
        whole = dataclasses.replace(whole, halves=(h0.model, h1.model))
    return whole


def calibrate_tracks(
    odometry: PoseTrack,
    truth: PoseTrack,
    window_m: float = DEFAULT_WINDOW_M,
    window_rad: float = DEFAULT_WINDOW_RAD,
    sonar_relative_error: float = DEFAULT_SONAR_RELATIVE_ERROR,
) -> Calibration | None:
    """:func:`fit` of the tracks (same stamps, shape (N,)) at the window and its
    :data:`JITTER_LADDER`; None when fewer than :data:`MIN_WINDOWS` windows are complete."""
    if len(truth) < 2:
        return None
    windows = compare_windows(odometry, truth, window_m, window_rad)
    if len(windows) < MIN_WINDOWS:
        return None
    ladder = [compare_windows(odometry, truth, window_m * k, window_rad * k) for k in JITTER_LADDER]
    ladder = [w for w in ladder if len(w) >= MIN_WINDOWS]
    return fit(windows, sonar_relative_error, ladder)


def _part(track: PoseTrack, start: int, stop: int | None) -> PoseTrack:
    sl = slice(start, stop)
    return PoseTrack(track.stamp_ns[sl], track.x_m[sl], track.y_m[sl], track.theta_rad[sl])
