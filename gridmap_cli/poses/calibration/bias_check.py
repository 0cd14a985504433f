"""Which of a calibration's biases hold across its own log, and so may be corrected as known.

``build --correct-odometry`` (the default of an error-aware map) takes the signed biases out of
the track of *another* log, or of another stretch of the same one. A bias is a claim that the
odometry makes the same error per metre (per radian) everywhere; the calibration log tests that
claim on itself by fitting each half of it apart (:func:`~.calibrate.calibrate`), and a bias is
written only when

    ``|b| >= SIGMA * se``, ``se = max(se_jackknife, |b1 - b2| / 2)``

with :data:`SIGMA` = 2 (about 95 % two-sided for a normal estimate). ``se_jackknife`` is the
whole's block-jackknife standard error; ``|b1 - b2| / 2`` is the standard error of the mean of
two independent estimates, what the halves themselves say the whole is worth. When the halves
differ by more than their own noise, the bias changes within the log (a floor, a load, a wheel)
and the next log has yet another value: the bias is then kept only when it is larger than the
halves' difference, so that correcting by it takes out more than it can put in. Correcting by an
estimate helps, in expectation, when the bias is larger than the estimate's error; 2 standard
errors ask that with the usual margin.

A bias that fails is dropped from the file (its signed value and its magnitude set to 0), so that
neither ``--correct-odometry`` nor a spread of it acts on it: a narrow spread costs an
error-aware map little, a wrong correction turns a whole track. Without halves (too little
travel to fit each) a bias cannot be checked and is dropped too. The reason given says which
standard error decided: :data:`DISAGREE` when the halves' difference was the larger.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from gridmap_cli.poses.odometry_error import BIAS_KEYS

#: Standard errors a bias must stand from 0 by to be written.
SIGMA = 2.0

APPLIED = "applied"
DISAGREE = "halves disagree"
NOT_SHOWN = "within noise of 0"
UNCHECKED = "halves not fitted"
NONE = "not estimated"


@dataclass(frozen=True)
class BiasCheck:
    """One bias (``key``, of :data:`~gridmap_cli.poses.odometry_error.BIAS_KEYS`): the whole
    log's estimate and standard error, each half's (None without halves), and the verdict:
    ``applied`` (kept in the file) and ``reason`` (:data:`APPLIED`, :data:`DISAGREE`,
    :data:`NOT_SHOWN`, :data:`UNCHECKED` or :data:`NONE`)."""

    key: str
    whole: float
    se: float
    halves: tuple[float, float] | None
    halves_se: tuple[float, float] | None
    applied: bool
    reason: str

    @property
    def disagreement(self) -> float:
        """The halves' difference in standard errors of the difference (nan without halves)."""
        if self.halves is None or self.halves_se is None:
            return math.nan
        spread = math.hypot(*self.halves_se)
        diff = abs(self.halves[0] - self.halves[1])
        return diff / spread if spread > 0 else (0.0 if diff == 0 else math.inf)

    def as_dict(self) -> dict[str, object]:
        def num(x: float) -> float | None:
            return x if math.isfinite(x) else None

        return {
            "whole": self.whole,
            "standard_error": num(self.se),
            "halves": list(self.halves) if self.halves else None,
            "halves_standard_error": [num(x) for x in self.halves_se] if self.halves_se else None,
            "applied": self.applied,
            "reason": self.reason,
        }


def check_bias(
    key: str,
    whole: float,
    se: float,
    halves: tuple[float, float] | None,
    halves_se: tuple[float, float] | None,
) -> BiasCheck:
    """The verdict on one bias (module docstring); standard errors may be infinite."""
    if key not in BIAS_KEYS:
        raise ValueError(f"not a bias: {key}")
    if whole == 0.0:
        return BiasCheck(key, whole, se, halves, halves_se, False, NONE)
    if halves is None or halves_se is None:
        return BiasCheck(key, whole, se, halves, halves_se, False, UNCHECKED)
    diff = abs(halves[0] - halves[1])
    worth = max(se, 0.5 * diff)
    if abs(whole) >= SIGMA * worth:
        return BiasCheck(key, whole, se, halves, halves_se, True, APPLIED)
    reason = DISAGREE if 0.5 * diff > se else NOT_SHOWN
    return BiasCheck(key, whole, se, halves, halves_se, False, reason)
