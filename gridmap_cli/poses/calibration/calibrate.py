"""Estimate the odometry-error model from a log with a reference track (docs/odometry-error.md).

The log is cut into consecutive windows of travel: a window ends as soon as the robot has driven
``window_m`` metres or turned ``window_rad`` radians (both measured on the reference) since it
began. Over each window the odometry's motion is compared with the reference's through what no
frame changes (the length of the window's displacement, the sum of its turns), so the error a
window shows is the error made within it, whatever the drift before it:

* distance error ``e_d = |odometry displacement| - |reference displacement|`` (metres);
* heading error ``e_h = odometry rotation - reference rotation`` (radians, signed sums of the
  wrapped heading increments, so a window may turn more than pi).

The log is cut again at :data:`JITTER_LADDER` times the window, and
:func:`~gridmap_cli.poses.calibration.robust_fit.robust_fit` fits all of these windows at once: the
*systematic* part, signed (distance scale, turn scale, heading drift per metre: a known bias
``build --correct-odometry`` takes out of the track), and the *random* part, the variance of
what is left, split into the reference's jitter (the same at every window length) and the
odometry's random walks (growing with the length), leaving out the windows a jump of the
reference spoils. The file gets the random walks, the systematic terms' magnitudes (the spread
of an uncorrected bias) and, version 3, their signs. The fit is made on the whole log and on
each half of it (by distance driven), so that the spread of every coefficient between the halves
shows whether it transfers.

A term the log cannot show (no rotation in a straight-line log) is reported as not estimated
and written as 0. Frames do not matter, so the odometry may start anywhere.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import GridmapError, InputFileError
from gridmap_cli.poses.calibration.bias_check import BiasCheck, check_bias
from gridmap_cli.poses.calibration.consistency import consistency
from gridmap_cli.poses.calibration.robust_fit import RobustFit, robust_fit, standard_errors
from gridmap_cli.poses.calibration.windows import (
    BUDGET_TOLERANCE,
    DEFAULT_WINDOW_M,
    DEFAULT_WINDOW_RAD,
    Windows,
    begin_indices,
    compare_windows,
    truth_at_odometry,
)
from gridmap_cli.poses.odometry_error import (
    BIAS_KEYS,
    DEFAULT_SONAR_RELATIVE_ERROR,
    MAX_BIAS,
    OdometryError,
    correct_track,
    travelled,
)
from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise
from gridmap_cli.records import PoseTrack, RangeLog

FloatArray = npt.NDArray[np.float64]

#: Fewer complete windows than this cannot separate a systematic error from a random one.
MIN_WINDOWS = 3
#: Turning less than this in all (truth) leaves the turn terms unestimated: a quarter turn.
MIN_ROTATION_RAD = math.pi / 2
#: The window lengths (multiples of the window and its turn budget) whose residuals separate the
#: reference's jitter (the same at every length) from the odometry's random walk (growing).
JITTER_LADDER = (1.0, 2.0, 5.0, 10.0, 20.0, 50.0)
#: The distance terms are fitted on the windows up to this many times the window: a longer
#: window's displacement is shortened by the heading error along it more than by the distance
#: error (the chord of a bent path).
DISTANCE_LADDER_MAX = 5.0
#: The heading's jitter and random walks are fitted on the windows of at least this many times
#: the window: a reference's heading error lasts metres (a scan matcher's in a turn) and, seen
#: over shorter windows, passes for a random walk of the odometry.
HEADING_LADDER_MIN = 5.0


class CalibrationError(GridmapError):
    """The log cannot be calibrated on: too little travel."""


@dataclass(frozen=True)
class LeftOut:
    """A window the robust fit left out: its length (``window_m``, the rung's budget), where it
    begins (seconds from the first pose, metres driven), its errors (metres, radians)."""

    window_m: float
    start_s: float
    start_m: float
    distance_error_m: float
    heading_error_rad: float

    def as_dict(self) -> dict[str, float]:
        return dataclasses.asdict(self)


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
    #: Windows of every length fitted, and those left out (:class:`LeftOut`).
    fitted_windows: int = 0
    left_out: tuple[LeftOut, ...] = ()
    #: The check on the positions (:mod:`.consistency`): actual over predicted position error
    #: at long horizons, the pairs it rests on, and the factor the random walks were scaled by.
    consistency: float = math.nan
    consistency_pairs: int = 0
    random_walk_scale: float = 1.0
    #: Standard errors of the random walks' variances (along, turn, heading per metre), the
    #: block jackknife's (:func:`~gridmap_cli.poses.calibration.robust_fit.walk_standard_errors`).
    walk_variance_se: tuple[float, float, float] = (math.inf, math.inf, math.inf)
    #: Which random walks the check on the positions scaled (along, turn, heading per metre).
    walk_checked: tuple[bool, bool, bool] = (False, False, False)
    #: Standard errors of the signed biases (distance scale, turn scale, heading drift), the
    #: block jackknife's.
    bias_se: tuple[float, float, float] = (math.inf, math.inf, math.inf)
    #: The check of each bias across the log's halves (:mod:`.bias_check`), in the order of
    #: :data:`~gridmap_cli.poses.odometry_error.BIAS_KEYS`; empty before it is made.
    bias_checks: tuple[BiasCheck, ...] = ()

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
            "robust": {
                "fitted_windows": self.fitted_windows,
                "left_out": [w.as_dict() for w in self.left_out],
            },
            "position_check": {
                "factor": self.consistency if math.isfinite(self.consistency) else None,
                "pairs": self.consistency_pairs,
                "scale": self.random_walk_scale,
                "cut": dict(zip(WALK_KEYS, self.walk_checked, strict=True)),
            },
            "bias_check": {c.key: c.as_dict() for c in self.bias_checks},
        }


def fit(
    windows: Windows,
    sonar_relative_error: float = DEFAULT_SONAR_RELATIVE_ERROR,
    ladder: Sequence[Windows] = (),
) -> Calibration:
    """Fit the model to compared windows (:mod:`gridmap_cli.poses.calibration.robust_fit` gives the
    estimators).

    ``ladder``: the same tracks cut into windows of other lengths. With two lengths or more
    (``windows`` counts as one), the reference's jitter is fitted too; otherwise the random
    walks come from ``windows`` alone, with no jitter.
    """
    full_m = windows.window_m - BUDGET_TOLERANCE  # a window's distance budget, used up
    driven = windows.driven_m
    disp = windows.displacement_m
    total_driven = float(driven.sum())
    total_turned = float(np.abs(windows.turned_rad).sum())
    distance_ok = bool(float(np.sum(disp**2)) > 0.0 and total_driven >= full_m)
    turn_ok = total_turned >= MIN_ROTATION_RAD
    drift_ok = total_driven >= full_m
    rungs = [windows, *(w for w in ladder if w.window_m != windows.window_m)]
    jitter_ok = len(rungs) >= 2
    rungs.sort(key=lambda w: w.window_m)
    if rungs[0] is not windows:  # the main window first: a ladder rung shorter than it follows
        rungs.remove(windows)
        rungs.insert(0, windows)
    short = sum(
        w.window_m <= DISTANCE_LADDER_MAX * windows.window_m + BUDGET_TOLERANCE for w in rungs
    )
    first_long = sum(
        w.window_m < HEADING_LADDER_MIN * windows.window_m - BUDGET_TOLERANCE for w in rungs
    )
    fit_args = ([w.rung() for w in rungs], distance_ok, turn_ok, drift_ok, jitter_ok, short,
                first_long)  # fmt: skip
    robust = robust_fit(*fit_args)
    walk_se, bias_se = standard_errors(*fit_args)
    # rounding noise of an error-free log (1e-17) is no error: write it as 0
    scale, turn_scale = _clean(robust.scale), _clean(robust.turn_scale)
    drift = _clean(robust.drift_rad_per_m)
    r_d = windows.distance_error_m - scale * disp
    r_h = windows.heading_error_rad - turn_scale * windows.turned_rad - drift * driven
    model = OdometryError(
        range_m_per_m=abs(scale),
        range_m_per_sqrt_m=_clean(robust.along_m_per_sqrt_m),
        bearing_rad_per_rad=abs(turn_scale),
        bearing_rad_per_sqrt_rad=_clean(robust.heading_rad_per_sqrt_rad),
        heading_drift_rad_per_m=abs(drift),
        sonar_relative_error=sonar_relative_error,
        heading_rad_per_sqrt_m=_clean(robust.heading_rad_per_sqrt_m),
        distance_scale_bias=_bias(scale),
        turn_scale_bias=_bias(turn_scale),
        heading_drift_bias_rad_per_m=_bias(drift),
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
        jitter_m=_clean(robust.jitter_m),
        jitter_rad=_clean(robust.jitter_rad),
        jitter_estimated=jitter_ok,
        fitted_windows=sum(len(w) for w in rungs),
        left_out=_left_out(rungs, robust),
        walk_variance_se=walk_se,
        bias_se=bias_se,
    )


def _left_out(rungs: list[Windows], robust: RobustFit) -> tuple[LeftOut, ...]:
    out = []
    for k, w in enumerate(rungs):
        for i in np.flatnonzero(robust.left_out(k)):
            out.append(
                LeftOut(
                    window_m=w.window_m,
                    start_s=float(w.start_s[i]),
                    start_m=float(w.start_m[i]),
                    distance_error_m=float(w.distance_error_m[i]),
                    heading_error_rad=float(w.heading_error_rad[i]),
                )
            )
    return tuple(out)


def _bias(x: float) -> float:
    """A signed systematic error as the file holds it (an absurd one, a scale off by half or
    more, is clipped: it says the reference and the odometry do not describe one motion)."""
    return float(np.clip(x, -MAX_BIAS * (1 - 1e-9), MAX_BIAS * (1 - 1e-9)))


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
    if log.odometry_missing is not None:
        raise InputFileError(
            log.source,
            f"calibrate compares the odometry with the reference track: odometry "
            f"{log.odometry_missing.split('; --pose global')[0]}",
        )
    odometry, truth = truth_at_odometry(log)
    whole = calibrate_tracks(
        odometry, truth, window_m, window_rad, sonar_relative_error, check=False
    )
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
    # halves of the travel in windows' worth (metres over the window, turns over its turn), so
    # that a log that turns on the spot has halves too
    dist, rot = travelled(truth)
    travel = dist / window_m + rot / window_rad
    cut = int(np.searchsorted(travel, 0.5 * travel[-1]))
    halves = [
        calibrate_tracks(o, t, window_m, window_rad, sonar_relative_error)
        for o, t in ((_part(odometry, 0, cut + 1), _part(truth, 0, cut + 1)),
                     (_part(odometry, cut, None), _part(truth, cut, None)))
    ]  # fmt: skip
    h0, h1 = halves
    if h0 is not None and h1 is not None:
        whole = dataclasses.replace(whole, halves=(h0.model, h1.model))
    # only the biases that hold across the log are written; the check on the positions then
    # judges the random walks around the track those leave
    return checked(held_biases(whole, h0, h1), odometry, truth)


def calibrate_tracks(
    odometry: PoseTrack,
    truth: PoseTrack,
    window_m: float = DEFAULT_WINDOW_M,
    window_rad: float = DEFAULT_WINDOW_RAD,
    sonar_relative_error: float = DEFAULT_SONAR_RELATIVE_ERROR,
    check: bool = True,
) -> Calibration | None:
    """:func:`fit` of the tracks (same stamps, shape (N,)) at the window and its
    :data:`JITTER_LADDER`, and (``check``) the check on the positions; None when fewer than
    :data:`MIN_WINDOWS` windows are complete."""
    if len(truth) < 2:
        return None
    windows = compare_windows(odometry, truth, window_m, window_rad)
    if len(windows) < MIN_WINDOWS:
        return None
    # the longer windows begin where each main window does: they overlap, so that the long
    # ones, which alone see through an error of the reference that lasts metres, are many too
    begins = begin_indices(odometry, truth, windows)
    ladder = [
        compare_windows(odometry, truth, window_m * k, window_rad * k, window_m, window_rad, begins)
        for k in JITTER_LADDER
    ]
    ladder = [w for w in ladder if len(w) >= MIN_WINDOWS]
    cal = fit(windows, sonar_relative_error, ladder)
    return checked(cal, odometry, truth) if check else cal


#: The magnitude keys of :data:`~gridmap_cli.poses.odometry_error.BIAS_KEYS`, in their order.
MAGNITUDE_KEYS = ("range_m_per_m", "bearing_rad_per_rad", "heading_drift_rad_per_m")


def signed_biases(cal: Calibration) -> tuple[tuple[float, bool], ...]:
    """The biases (signed, in the order of ``BIAS_KEYS``) and whether the log showed each."""
    return (
        (cal.scale_error, cal.distance_estimated),
        (cal.turn_scale_error, cal.turn_estimated),
        (cal.heading_drift_rad_per_m, cal.drift_estimated),
    )


def held_biases(
    whole: Calibration, first: Calibration | None, second: Calibration | None
) -> Calibration:
    """``whole`` with each bias checked across the halves (:mod:`.bias_check`) and those that
    do not hold dropped from its model, signed value and magnitude: the file then holds what
    the calibration knows and no more."""
    checks = []
    model = whole.model
    for k, key in enumerate(BIAS_KEYS):
        shown = signed_biases(whole)[k][1]
        b = getattr(model, key) if shown else 0.0
        halves = halves_se = None
        if first is not None and second is not None:
            (b1, ok1), (b2, ok2) = signed_biases(first)[k], signed_biases(second)[k]
            if ok1 and ok2:  # a half that could not show the term cannot check it
                halves, halves_se = (b1, b2), (first.bias_se[k], second.bias_se[k])
        check = check_bias(key, b, whole.bias_se[k], halves, halves_se)
        checks.append(check)
        if not check.applied:
            model = dataclasses.replace(model, **{key: 0.0, MAGNITUDE_KEYS[k]: 0.0})
    return dataclasses.replace(whole, model=model, bias_checks=tuple(checks))


#: The random walks' keys, in the order of :attr:`Calibration.walk_checked`.
WALK_KEYS = ("range_m_per_sqrt_m", "bearing_rad_per_sqrt_rad", "heading_rad_per_sqrt_m")
#: A random walk whose variance is less than this many of its standard errors is not shown by
#: the windows (the log is too short to tell it from noise): the check on the positions may cut
#: it down.
WALK_SIGNIFICANT = 2.0


def checked(cal: Calibration, odometry: PoseTrack, truth: PoseTrack) -> Calibration:
    """``cal`` with the check on the positions (:mod:`.consistency`) made, and the random walks
    the windows could not show (less than :data:`WALK_SIGNIFICANT` standard errors) cut down by
    its factor where it is below 1: such a walk predicts more error at a map's lengths than the
    calibration's own track shows. A walk the windows show stands, and none is raised: an error
    the positions show beyond the walks is what the robust fit left out (a wheel slip, a
    reference jump), and spread over a whole map it would blur every other part of it."""
    noise = StepNoise.of(cal.model.random_part())
    factor, pairs = consistency(
        correct_track(odometry, cal.model), truth, noise, cal.jitter_m, cal.jitter_rad,
        cal.window_m, cal.window_rad,
    )  # fmt: skip
    out = dataclasses.replace(cal, consistency=factor, consistency_pairs=pairs)
    if not (math.isfinite(factor) and factor < 1.0):
        return out
    m = cal.model
    walks = (m.range_m_per_sqrt_m, m.bearing_rad_per_sqrt_rad, m.heading_rad_per_sqrt_m)
    se = cal.walk_variance_se
    weak = (_weak(walks[0], se[0]), _weak(walks[1], se[1]), _weak(walks[2], se[2]))
    if not any(weak):
        return out
    along, turn, per_m = (q * factor if w else q for q, w in zip(walks, weak, strict=True))
    model = dataclasses.replace(
        m, range_m_per_sqrt_m=along, bearing_rad_per_sqrt_rad=turn, heading_rad_per_sqrt_m=per_m
    )
    return dataclasses.replace(out, model=model, random_walk_scale=factor, walk_checked=weak)


def _weak(walk: float, variance_se: float) -> bool:
    """Whether a random walk's variance is within :data:`WALK_SIGNIFICANT` standard errors of
    0 (a walk of 0 is nothing to cut)."""
    return bool(walk > 0.0 and walk * walk < WALK_SIGNIFICANT * variance_se)


def _part(track: PoseTrack, start: int, stop: int | None) -> PoseTrack:
    sl = slice(start, stop)
    return PoseTrack(track.stamp_ns[sl], track.x_m[sl], track.y_m[sl], track.theta_rad[sl])
