"""The log being mapped checks the odometry-error file it is given, when its laser can.

A calibration file describes another log (or another stretch of this one). Where the log being
mapped has a laser, its scans matched one after another (:mod:`~gridmap_cli.poses.correction.
scan_match`, no loop closure) are a local reference for its own odometry, good over the tens
of metres a bias and a random walk act on. Against it the build fits the log's own biases (the
robust fit of ``gridmap calibrate``, with the standard errors of its block jackknife) and checks
the file:

* **a bias** of the file is dropped (signed value and magnitude) when correcting by it would
  leave this log with more bias than not correcting, by more than :data:`~.bias_check.SIGMA` of
  the standard errors of the log's own estimate ``b``: ``|b - b_file| - |b| > SIGMA * se``. The
  log's own estimate is not put in its place: a scan matcher has biases of its own (along a
  featureless corridor) and a correction of the map's log by its own reference is another
  product (``--pose scan-matched``);
* **the random walks** are checked on the positions, as calibrate checks its own
  (:func:`~.consistency.consistency`): from every key pose the corrected odometry is compared
  with the scan-matched track after 20 to 500 key steps, against the covariance the walks
  predict plus the scan matcher's own jitter. When the log's odometry strays less than the
  walks predict (the factor below 1), the walks are scaled down by the factor: a spread wider
  than the log's own error blurs its map for nothing. They are never scaled up: an error beyond
  the walks may be the scan matcher's, and spread over the whole map it would blur every part.

A log without a laser, or too short to fit (:data:`~.calibrate.MIN_WINDOWS` windows), keeps the
file as it is; :class:`FileCheck` says which happened.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from gridmap_cli.poses.calibration import bias_check
from gridmap_cli.poses.calibration.calibrate import (
    MAGNITUDE_KEYS,
    WALK_KEYS,
    calibrate_tracks,
    signed_biases,
)
from gridmap_cli.poses.calibration.consistency import consistency
from gridmap_cli.poses.correction.scan_match import NoLaserError, match_log
from gridmap_cli.poses.odometry_error import BIAS_KEYS, OdometryError, correct_track
from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RobotDescription


@dataclass(frozen=True)
class FileCheck:
    """What the log made of the file: ``model`` is what the build uses. ``checked``: whether
    a laser checked it at all (``why`` says why not). ``dropped``: the biases of the file the
    log's own estimates disagree with, each with the log's estimate and standard error.
    ``walk_factor``: what the random walks were multiplied by (1: kept)."""

    model: OdometryError
    checked: bool
    why: str = ""
    dropped: tuple[tuple[str, float, float, float], ...] = ()
    walk_factor: float = 1.0
    consistency: float = math.nan
    #: The random walks narrowed to this log's own (:data:`~.calibrate.WALK_KEYS`).
    narrowed: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, object]:
        return {
            "checked": self.checked,
            "why": self.why or None,
            "biases_dropped": {
                key: {"file": f, "this_log": own, "standard_error": se}
                for key, f, own, se in self.dropped
            },
            "walks_narrowed_to_this_log": list(self.narrowed),
            "position_check": self.consistency if math.isfinite(self.consistency) else None,
            "random_walk_scale": self.walk_factor,
        }

    def summary(self) -> str:
        """One line for the build's summary: what was done to the file, or why nothing."""
        if not self.checked:
            return f"odometry error not checked ({self.why})"
        parts = []
        if self.dropped:
            names = ", ".join(key.removesuffix("_rad_per_m") for key, *_ in self.dropped)
            parts.append(f"{names} not corrected (this log's laser disagrees)")
        if self.narrowed:
            parts.append(f"{', '.join(self.narrowed)} narrowed to this log's own")
        if self.walk_factor < 1.0:
            parts.append(f"random walks x {self.walk_factor:.2f} (the log strays less)")
        if not parts:
            parts.append("the file holds")
        return "odometry error checked against the laser: " + "; ".join(parts)


def check_file(log: RangeLog, robot: RobotDescription | None, model: OdometryError) -> FileCheck:
    """Check ``model`` against ``log``'s own scan-matched track (module docstring)."""
    if StepNoise.of(model).is_zero and not model.has_bias:
        return FileCheck(model, False, "the file holds no error")
    try:
        match = match_log(log, robot)
    except NoLaserError:
        return FileCheck(model, False, "no laser in the log")
    # the odometry at the scans' stamps and the matched poses there
    odometry, reference = match.odometry, match.track
    if len(reference) < 2:
        return FileCheck(model, False, "too few scans")
    own = calibrate_tracks(odometry, reference)
    if own is None:
        return FileCheck(model, False, "too little travel")
    dropped = []
    kept = model
    for k, key in enumerate(BIAS_KEYS):
        bias = getattr(model, key)
        value, shown = signed_biases(own)[k]
        se = own.bias_se[k]
        if bias == 0.0 or not shown or not math.isfinite(se):
            continue
        # corrected by the file, this log keeps |value - bias| of bias; uncorrected, |value|
        if abs(value - bias) - abs(value) > bias_check.SIGMA * se:
            dropped.append((key, bias, value, se))
            kept = dataclasses.replace(kept, **{key: 0.0, MAGNITUDE_KEYS[k]: 0.0})
    # each walk no wider than this log's own (its windows against the laser, the scan
    # matcher's jitter taken out), then the walks judged on the positions
    walks = {w: min(getattr(kept, w), getattr(own.model, w)) for w in WALK_KEYS}
    narrowed = tuple(w for w in WALK_KEYS if walks[w] < getattr(kept, w))
    kept = dataclasses.replace(kept, **walks)
    noise = StepNoise.of(kept.random_part())
    factor, _ = consistency(
        correct_track(odometry, kept), reference, noise, own.jitter_m, own.jitter_rad,
        own.window_m, own.window_rad,
    )  # fmt: skip
    scale = factor if math.isfinite(factor) and factor < 1.0 else 1.0
    if scale < 1.0:
        kept = dataclasses.replace(kept, **{w: getattr(kept, w) * scale for w in WALK_KEYS})
    return FileCheck(kept, True, "", tuple(dropped), scale, factor, narrowed)
