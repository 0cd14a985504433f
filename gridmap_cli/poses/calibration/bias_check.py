"""Which of a calibration's biases hold across its own log, and so may be corrected as known.

``build --correct-odometry`` (the default of an error-aware map) takes the signed biases out of
the track of *another* log, or of another stretch of the same one. A bias is a claim that the
odometry makes the same error per metre (per radian) everywhere; the calibration log can test
that claim on itself, by fitting each half of it apart (:func:`~.calibrate.calibrate`). Two
tests, each at :data:`SIGMA` standard errors (about 95 % two-sided for a normal estimate):

* **the halves agree**: ``|b1 - b2| <= SIGMA * sqrt(se1**2 + se2**2)``, the standard errors
  the halves' own block jackknives give. Under one constant bias the difference of two
  independent estimates is zero-mean with that spread; a larger one says the bias changed
  within the log (a floor, a load, a tyre), and the next log will have yet another;
* **the whole shows it**: ``|b| >= SIGMA * se``, with ``se`` the larger of the whole's jackknife
  standard error and half the halves' difference (the standard error of the mean of two
  independent estimates, what the halves say the whole's estimate is worth). A bias not
  distinguishable from 0 is not known: correcting by it adds as much error as it takes out.

A bias that fails either is dropped from the file (its signed value and its magnitude set to
0), so that neither ``--correct-odometry`` nor a spread of it acts on it: a narrow spread costs
an error-aware map little, a wrong correction turns a whole track. Without halves (too little
travel to fit each) a bias cannot be checked and is dropped too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from gridmap_cli.poses.odometry_error import BIAS_KEYS

#: Standard errors a bias's halves may differ by, and the whole must stand from 0 by.
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
    if not diff <= SIGMA * math.hypot(*halves_se):
        return BiasCheck(key, whole, se, halves, halves_se, False, DISAGREE)
    worth = max(se, 0.5 * diff)
    if not abs(whole) >= SIGMA * worth:
        return BiasCheck(key, whole, se, halves, halves_se, False, NOT_SHOWN)
    return BiasCheck(key, whole, se, halves, halves_se, True, APPLIED)
