"""The robust fit behind ``gridmap calibrate``: systematic errors, random walks, jitter, outliers.

Input: windows of travel at several lengths (the *rungs*, :class:`Rung`), each window with what
the reference drove (``d``, metres), turned (``t``, signed net radians) and displaced (``D``,
metres), and the odometry's distance and heading errors over it (``e_d``, ``e_h``). The model:

* systematic, signed: ``e_d = a D``, ``e_h = u t + c d`` (distance scale ``a``, turn scale ``u``,
  heading drift per metre ``c``);
* random, the variance of what is left, per window:
  ``var r_d = J_d + q_a d`` and ``var r_h = J_h + q_t T + q_h d`` (``T`` the absolute net
  turns of the window's key steps, summed, as build's pose uncertainty adds them up): the
  intercepts are the reference's own jitter (twice: at the window's start and at its end,
  whatever its length), the slopes the odometry's random walks (growing with what was driven or
  turned). All >= 0. A stamp offset (the odometry's stamps ``lag`` seconds off the
  reference's) is a systematic heading error too: ``lag`` times the change of the reference's
  turn rate between the window's ends, fitted with the others.

A reference jumps now and then (a SLAM track snapping at a loop closure, a stamp a little off
during a fast turn): a least-squares fit of squared residuals takes such a window's error
squared, and one jump can double a random walk. So the fit is iterated: start from a robust
scale (the median absolute residual of each rung), leave out every window whose residual is more
than :data:`OUTLIER_SIGMA` of its modelled standard deviation, fit the systematic terms by
weighted least squares (weights ``1 / var``) and the variances by non-negative weighted least
squares of the squared residuals (weights ``1 / var**2``, the variance of a squared normal)
on the windows kept, and repeat until the set kept no longer changes. The variances are scaled
up by :data:`TRUNCATION_VARIANCE`, what cutting a normal at that many sigma takes off.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import nnls

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: A window whose residual exceeds this many modelled standard deviations is left out.
OUTLIER_SIGMA = 3.0
#: Variance of a standard normal cut at +-OUTLIER_SIGMA: 1 - 2 c phi(c) / (2 Phi(c) - 1).
TRUNCATION_VARIANCE = 1.0 - (
    2.0 * OUTLIER_SIGMA * math.exp(-0.5 * OUTLIER_SIGMA**2) / math.sqrt(2.0 * math.pi)
) / math.erf(OUTLIER_SIGMA / math.sqrt(2.0))
#: Median of |z| for a standard normal z: turns a median absolute residual into a sigma.
MEDIAN_ABS_NORMAL = 0.6744897501960817
#: The largest share of the windows left out (of their distance or of their heading errors).
MAX_LEFT_OUT = 0.1
#: Rounds of leaving out and refitting; the set kept settles in two or three.
MAX_ROUNDS = 10
#: The smallest variance a window is weighted by (m**2 or rad**2): an error-free log has 0.
MIN_VARIANCE = 1e-18


@dataclass(frozen=True)
class Rung:
    """The windows of one length, shape (W,) each (see the module docstring for the names);
    ``start_s``: each window's start, seconds from the first pose; ``start_m``: metres the
    reference had driven by then."""

    driven_m: FloatArray
    turned_rad: FloatArray
    displacement_m: FloatArray
    distance_error_m: FloatArray
    heading_error_rad: FloatArray
    start_s: FloatArray
    start_m: FloatArray
    window_m: float
    #: What the turning random walk grows with (radians >= 0): the absolute net turns of the
    #: window's key steps, summed.
    key_turned_rad: FloatArray
    #: The reference's turn rate at the window's end less that at its start (rad/s).
    turn_rate_change: FloatArray
    #: Where the window begins and ends in travel (key steps' worth of metres and turns):
    #: the jackknife's blocks.
    start_travel: FloatArray
    end_travel: FloatArray


@dataclass(frozen=True)
class RobustFit:
    """What :func:`robust_fit` found. Systematic terms signed; random walks and jitters as
    standard deviations (per sqrt unit, per pose); ``kept_distance``, ``kept_heading``: per
    rung, the windows whose distance (heading) error was used."""

    scale: float
    turn_scale: float
    drift_rad_per_m: float
    along_m_per_sqrt_m: float
    heading_rad_per_sqrt_rad: float
    heading_rad_per_sqrt_m: float
    jitter_m: float
    jitter_rad: float
    #: How far the odometry's stamps run ahead of the reference's (seconds): a heading error
    #: of lag_s times the change of the turn rate over a window.
    lag_s: float
    kept_distance: tuple[BoolArray, ...]
    kept_heading: tuple[BoolArray, ...]
    rounds: int
    #: The rungs the distance terms were fitted on: the first this many.
    distance_rungs: int

    def left_out(self, rung: int) -> BoolArray:
        """The windows of ``rung`` left out, for their distance or heading error (W,); a rung
        the distance terms do not use counts its heading errors alone."""
        distance = self.kept_distance[rung] | (rung >= self.distance_rungs)
        return ~(distance & self.kept_heading[rung])


def robust_fit(
    rungs: list[Rung],
    distance_ok: bool,
    turn_ok: bool,
    drift_ok: bool,
    jitter_ok: bool,
    distance_rungs: int | None = None,
    heading_walk_from: int = 0,
) -> RobustFit:
    """Fit the model of the module docstring to ``rungs`` (the first is the main window).

    ``*_ok``: which terms the log can show (the others are held at 0); ``jitter_ok``: fit the
    intercepts (needs two lengths of window or more). ``distance_rungs``: the distance terms
    are fitted on the first this many rungs only (default all): over a long window the length
    of the displacement depends on the heading error along it more than on the distance error.
    The heading's systematic terms use every rung: the long windows show them best.
    ``heading_walk_from``: the heading's variance (jitter and random walks) is fitted on the
    rungs from this one on: over a short window the reference's own heading error, which lasts
    a few metres and does not add up, looks like a random walk of the odometry.
    """
    d = np.concatenate([r.driven_m for r in rungs])
    t = np.concatenate([r.turned_rad for r in rungs])
    key_t = np.concatenate([r.key_turned_rad for r in rungs])
    d_rate = np.concatenate([r.turn_rate_change for r in rungs])
    disp = np.concatenate([r.displacement_m for r in rungs])
    e_d = np.concatenate([r.distance_error_m for r in rungs])
    e_h = np.concatenate([r.heading_error_rad for r in rungs])
    rung = np.concatenate([np.full(len(r.driven_m), k) for k, r in enumerate(rungs)])
    short = rung < (len(rungs) if distance_rungs is None else max(distance_rungs, 1))
    long = rung >= min(heading_walk_from, len(rungs) - 1)
    ones = np.ones_like(d)
    sys_d, sys_d_names = _design([("a", disp, distance_ok)])
    lag_ok = turn_ok and bool(np.any(d_rate))
    sys_h, sys_h_names = _design([("u", t, turn_ok), ("c", d, drift_ok), ("lag", d_rate, lag_ok)])
    var_d_design, vd_names = _design([("1", ones, jitter_ok), ("d", d, distance_ok)])
    var_h_design, vh_names = _design(
        [("1", ones, jitter_ok), ("t", key_t, turn_ok), ("d", d, drift_ok)]
    )
    # round 0: unweighted systematic fit, robust per-rung scale
    a = _wls(sys_d, e_d, np.ones_like(d))
    b = _wls(sys_h, e_h, np.ones_like(d))
    r_d, r_h = e_d - sys_d @ a, e_h - sys_h @ b
    var_d, var_h = _rung_scale(r_d, rung), _rung_scale(r_h, rung)
    # the distance and the heading errors are left out separately: a stamp a little off in a
    # fast turn spoils the heading error of a window, not its length
    kd, kh = _inliers(r_d, var_d, short), _inliers(r_h, var_h)
    vd_coef = np.zeros(var_d_design.shape[1])
    vh_coef = np.zeros(var_h_design.shape[1])
    rounds = 0
    for rounds in range(1, MAX_ROUNDS + 1):  # noqa: B007 (the rounds made are reported)
        a = _wls(sys_d[kd], e_d[kd], 1.0 / var_d[kd])
        b = _wls(sys_h[kh], e_h[kh], 1.0 / var_h[kh])
        r_d, r_h = e_d - sys_d @ a, e_h - sys_h @ b
        vd_coef = _variance_fit(var_d_design[kd], r_d[kd] ** 2, var_d[kd])
        kv = kh & long
        vh_coef = _variance_fit(var_h_design[kv], r_h[kv] ** 2, var_h[kv])
        var_d = np.maximum(var_d_design @ vd_coef, MIN_VARIANCE)
        var_h = np.maximum(var_h_design @ vh_coef, MIN_VARIANCE)
        new_d, new_h = _inliers(r_d, var_d, short), _inliers(r_h, var_h)
        if np.array_equal(new_d, kd) and np.array_equal(new_h, kh):
            break
        kd, kh = new_d, new_h
    vd = dict(zip(vd_names, vd_coef, strict=True))
    vh = dict(zip(vh_names, vh_coef, strict=True))
    sa = dict(zip(sys_d_names, a, strict=True))
    sb = dict(zip(sys_h_names, b, strict=True))
    split = np.cumsum([len(r.driven_m) for r in rungs])[:-1]
    return RobustFit(
        scale=float(sa.get("a", 0.0)),
        turn_scale=float(sb.get("u", 0.0)),
        drift_rad_per_m=float(sb.get("c", 0.0)),
        lag_s=float(sb.get("lag", 0.0)),
        along_m_per_sqrt_m=_sd(vd.get("d", 0.0)),
        heading_rad_per_sqrt_rad=_sd(vh.get("t", 0.0)),
        heading_rad_per_sqrt_m=_sd(vh.get("d", 0.0)),
        jitter_m=_sd(vd.get("1", 0.0) / 2.0) if distance_ok else 0.0,
        jitter_rad=_sd(vh.get("1", 0.0) / 2.0),
        kept_distance=tuple(np.split(kd, split)),
        kept_heading=tuple(np.split(kh, split)),
        rounds=rounds,
        distance_rungs=len(rungs) if distance_rungs is None else max(distance_rungs, 1),
    )


def _design(columns: list[tuple[str, FloatArray, bool]]) -> tuple[FloatArray, tuple[str, ...]]:
    """The columns that are used, side by side (shape (W, P), P >= 0), and their names."""
    used = [(name, c) for name, c, ok in columns if ok]
    width = columns[0][1].shape[0]
    matrix = np.column_stack([c for _, c in used]) if used else np.zeros((width, 0))
    return np.asarray(matrix, dtype=np.float64), tuple(name for name, _ in used)


def _sd(variance: float) -> float:
    """A fitted variance as the standard deviation of the untruncated normal."""
    return math.sqrt(max(variance, 0.0) / TRUNCATION_VARIANCE)


def _wls(design: FloatArray, y: FloatArray, w: FloatArray) -> FloatArray:
    """Weighted least squares (weights ``w``, shape (W,)); zeros for an empty design."""
    if design.shape[1] == 0 or y.size == 0:
        return np.zeros(design.shape[1])
    sw = np.sqrt(w)
    solution, *_ = np.linalg.lstsq(design * sw[:, None], y * sw, rcond=None)
    return np.asarray(solution, dtype=np.float64)


def _variance_fit(design: FloatArray, r2: FloatArray, var: FloatArray) -> FloatArray:
    """Non-negative weighted least squares of squared residuals (weights ``1 / var**2``)."""
    if design.shape[1] == 0 or r2.size == 0:
        return np.zeros(design.shape[1])
    w = 1.0 / np.maximum(var, MIN_VARIANCE)
    # scale the columns so that nnls sees numbers near 1 (variances of 1e-6 m**2 are usual)
    a = design * w[:, None]
    norm = np.maximum(np.linalg.norm(a, axis=0), 1e-300)
    coef, _ = nnls(a / norm, r2 * w)
    return np.asarray(coef / norm, dtype=np.float64)


def _rung_scale(r: FloatArray, rung: npt.NDArray[np.int64]) -> FloatArray:
    """Each window's variance, the robust one of its rung: (median |r| / 0.674)**2."""
    out = np.empty_like(r)
    for k in np.unique(rung):
        sel = rung == k
        sigma = float(np.median(np.abs(r[sel]))) / MEDIAN_ABS_NORMAL
        out[sel] = max(sigma * sigma, MIN_VARIANCE)
    return out


def _inliers(r: FloatArray, var: FloatArray, use: BoolArray | None = None) -> BoolArray:
    """Windows within :data:`OUTLIER_SIGMA` of their standard deviation (an error-free log's
    residuals, rounding noise, are all kept); at most :data:`MAX_LEFT_OUT` of them are left
    out, the farthest, so that a variance model that fits badly for a round cannot shed the
    windows that would correct it. ``use``: the windows to consider (the others are not kept)."""
    use = np.ones(r.size, dtype=bool) if use is None else use
    z2 = r * r / var
    keep = ((z2 <= OUTLIER_SIGMA**2) | (np.abs(r) < 1e-9)) & use
    cap = int(MAX_LEFT_OUT * np.count_nonzero(use))
    if np.count_nonzero(use & ~keep) > cap:
        order = np.argsort(-np.where(use & ~keep, z2, -np.inf), kind="stable")
        keep = use.copy()
        keep[order[:cap]] = False
    return np.asarray(keep, dtype=np.bool_)


#: Blocks of travel the jackknife leaves out one at a time (:func:`walk_standard_errors`).
JACKKNIFE_BLOCKS = 8


def walk_standard_errors(
    rungs: list[Rung],
    distance_ok: bool,
    turn_ok: bool,
    drift_ok: bool,
    jitter_ok: bool,
    distance_rungs: int | None = None,
    heading_walk_from: int = 0,
) -> tuple[float, float, float]:
    """Standard errors of the random walks' variances: :func:`standard_errors`' first half."""
    return standard_errors(
        rungs, distance_ok, turn_ok, drift_ok, jitter_ok, distance_rungs, heading_walk_from
    )[0]


Triple = tuple[float, float, float]


def standard_errors(
    rungs: list[Rung],
    distance_ok: bool,
    turn_ok: bool,
    drift_ok: bool,
    jitter_ok: bool,
    distance_rungs: int | None = None,
    heading_walk_from: int = 0,
) -> tuple[Triple, Triple]:
    """Standard errors of the random walks' variances (``along_m_per_sqrt_m**2``,
    ``heading_rad_per_sqrt_rad**2``, ``heading_rad_per_sqrt_m**2``) and of the biases (distance
    scale, turn scale, heading drift per metre) by a delete-a-block jackknife: the travel cut
    into :data:`JACKKNIFE_BLOCKS` blocks, :func:`robust_fit` (same arguments) made again
    without the windows that touch each block in turn. The overlapping windows of one length
    are far from independent (fifty 50 m windows in 100 m of travel are two), which a block
    jackknife sees and the fit's own weights do not. Infinite without travel."""
    inf = (math.inf, math.inf, math.inf)
    end = max((float(np.max(r.end_travel)) for r in rungs if r.end_travel.size), default=0)
    if not end > 0.0:
        return inf, inf
    values = []
    for b in range(JACKKNIFE_BLOCKS):
        lo, hi = b * end / JACKKNIFE_BLOCKS, (b + 1) * end / JACKKNIFE_BLOCKS
        kept = [_subset(r, (r.end_travel <= lo) | (r.start_travel >= hi)) for r in rungs]
        fit = robust_fit(
            kept, distance_ok, turn_ok, drift_ok, jitter_ok, distance_rungs, heading_walk_from
        )
        values.append((*_walk_variances(fit), fit.scale, fit.turn_scale, fit.drift_rad_per_m))
    v = np.array(values)
    n = JACKKNIFE_BLOCKS
    se = np.sqrt((n - 1) / n * np.sum((v - v.mean(axis=0)) ** 2, axis=0))
    return (float(se[0]), float(se[1]), float(se[2])), (float(se[3]), float(se[4]), float(se[5]))


def _walk_variances(fit: RobustFit) -> tuple[float, float, float]:
    return (
        fit.along_m_per_sqrt_m**2,
        fit.heading_rad_per_sqrt_rad**2,
        fit.heading_rad_per_sqrt_m**2,
    )


def _subset(rung: Rung, keep: BoolArray) -> Rung:
    """The windows of ``rung`` where ``keep`` holds."""
    arrays = {
        name: value[keep] for name, value in vars(rung).items() if isinstance(value, np.ndarray)
    }
    return dataclasses.replace(rung, **arrays)  # type: ignore[arg-type]
