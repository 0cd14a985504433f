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
* **a bias at a map's lengths**, on the log's own revisits (:func:`biases_on_revisits`): the
  places the closure search finds seen twice, far apart along the path, registered scan on
  scan. A bias the windows cannot contradict (one that acts over the whole log, a turn scale
  over every net turn, fitted on windows the scan matcher's own jitter spoils) can still turn
  the whole track; the corrected odometry between the two visits, with the bias corrected and
  without it, is weighed by its likelihood, and a bias the revisits reject at
  :data:`~.bias_check.SIGMA` is not corrected;
* **a bias the revisits lean against is not corrected unless the laser confirms it**: when the
  revisits find the track without it the likelier at all (the statistic above 0), the bias
  stands only if the laser's windows confirm it (correcting by the file takes out more of the
  log's own bias than :data:`~.bias_check.SIGMA` standard errors: ``|b| - |b - b_file| > SIGMA
  * se``). A file may be of another robot, or of another floor; where the log can weigh the
  claim and nothing in it backs it, the drift-blind track is the safe side. Without revisits
  the file's bias stands as the other checks leave it: a stretch too short to come back
  anywhere has nothing to weigh it with, and a calibration of the same robot is the likelier
  file;
* **the random walks** are checked on the positions, as calibrate checks its own
  (:func:`~.consistency.consistency`): from every key pose the corrected odometry is compared
  with the scan-matched track after 20 to 500 key steps, against the covariance the walks
  predict plus the scan matcher's own jitter. When the log's odometry strays less than the
  walks predict (the factor below 1), the walks are scaled down by the factor: a spread wider
  than the log's own error blurs its map for nothing. They are never scaled up: an error beyond
  the walks may be the scan matcher's, and spread over the whole map it would blur every part.
* **the random walks at a map's lengths**, on the log's own revisits (:mod:`.revisit_check`):
  the places the closure search finds seen twice, far apart along the path, registered scan on
  scan. When the corrected odometry strays less between the two visits than the walks predict,
  the walks this log's windows do not show (:data:`~.calibrate.WALK_SIGNIFICANT` standard errors)
  are cut by that factor, as calibrate cuts them on its own positions; none is raised.

A log without a laser, or too short to fit (:data:`~.calibrate.MIN_WINDOWS` windows), keeps the
file as it is; :class:`FileCheck` says which happened.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Collection
from dataclasses import dataclass

from gridmap_cli.poses.calibration import bias_check
from gridmap_cli.poses.calibration.calibrate import (
    MAGNITUDE_KEYS,
    WALK_KEYS,
    WALK_SIGNIFICANT,
    calibrate_tracks,
    signed_biases,
)
from gridmap_cli.poses.calibration.consistency import consistency
from gridmap_cli.poses.calibration.revisit_check import (
    RevisitFactor,
    likelihood_ratio,
    revisit_factor,
)
from gridmap_cli.poses.correction.scan_match import (
    NoLaserError,
    ScanMatchParams,
    log_scans,
    match_scans,
)
from gridmap_cli.poses.correction.slam import SlamParams, optimise_with_closures
from gridmap_cli.poses.odometry_error import BIAS_KEYS, OdometryError, correct_track
from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RobotDescription

#: The closure search of the check on the revisits: one round on the scan-matched track. Later
#: rounds seek more closures on the track the first ones bent, which a graph's map needs and a
#: median over the revisits does not; one round costs about half as much.
REVISIT_SEARCH = SlamParams(rounds=1)


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
    #: The check on the revisits: how many, the factor, and the walks it cut (by the factor).
    revisits: int = 0
    revisit_factor: float = math.nan
    revisit_cut: tuple[str, ...] = ()
    #: The biases the log's revisits contradict (:func:`biases_on_revisits`), each with the
    #: revisits and the likelihood-ratio statistic that did.
    contradicted: tuple[tuple[str, int, float], ...] = ()
    #: The biases the log's revisits lean against and its laser does not confirm, each with the
    #: revisits and their statistic (:func:`biases_on_revisits`): not corrected.
    unconfirmed: tuple[tuple[str, int, float], ...] = ()

    def as_dict(self) -> dict[str, object]:
        return {
            "checked": self.checked,
            "why": self.why or None,
            "biases_dropped": {
                key: {"file": f, "this_log": own, "standard_error": se}
                for key, f, own, se in self.dropped
            },
            "biases_contradicted_by_revisits": _by_key(self.contradicted),
            "biases_not_confirmed": _by_key(self.unconfirmed),
            "walks_narrowed_to_this_log": list(self.narrowed),
            "position_check": self.consistency if math.isfinite(self.consistency) else None,
            "random_walk_scale": self.walk_factor,
            "revisits": {
                "count": self.revisits,
                "factor": self.revisit_factor if math.isfinite(self.revisit_factor) else None,
                "walks_cut": list(self.revisit_cut),
            },
        }

    def summary(self) -> str:
        """One line for the build's summary: what was done to the file, or why nothing."""
        if not self.checked:
            return f"odometry error not checked ({self.why})"
        parts = []
        if self.dropped:
            names = ", ".join(key.removesuffix("_rad_per_m") for key, *_ in self.dropped)
            parts.append(f"{names} not corrected (this log's laser disagrees)")
        for key, n, statistic in self.contradicted:
            parts.append(
                f"{key.removesuffix('_rad_per_m')} not corrected (this log's {n} revisits fit "
                f"better without it: likelihood ratio {statistic:.1f} > {bias_check.SIGMA**2:g})"
            )
        for key, n, statistic in self.unconfirmed:
            parts.append(
                f"{key.removesuffix('_rad_per_m')} not corrected (this log's {n} revisits lean "
                f"against it, likelihood ratio {statistic:.1f} > 0, and its laser does not "
                f"confirm it)"
            )
        if self.narrowed:
            parts.append(f"{', '.join(self.narrowed)} narrowed to this log's own")
        if self.walk_factor < 1.0:
            parts.append(f"random walks x {self.walk_factor:.2f} (the log strays less)")
        if math.isfinite(self.revisit_factor):
            cut = f"walks cut by {self.revisit_factor:.2f}" if self.revisit_cut else "walks kept"
            parts.append(
                f"the log's {self.revisits} revisits show the odometry within "
                f"{self.revisit_factor:.2f} of what the file predicts: {cut}"
            )
        if not parts:
            parts.append("the file holds")
        return "odometry error checked against the laser: " + "; ".join(parts)


def _by_key(verdicts: tuple[tuple[str, int, float], ...]) -> dict[str, dict[str, float]]:
    """The revisits' verdicts on biases (key, revisits, statistic) as ``--json`` gives them."""
    return {key: {"revisits": n, "likelihood_ratio_statistic": x} for key, n, x in verdicts}


def check_file(log: RangeLog, robot: RobotDescription | None, model: OdometryError) -> FileCheck:
    """Check ``model`` against ``log``'s own scan-matched track (module docstring)."""
    if StepNoise.of(model).is_zero and not model.has_bias:
        return FileCheck(model, False, "the file holds no error")
    params = ScanMatchParams()
    try:
        scans = log_scans(log, robot, params)
    except NoLaserError:
        return FileCheck(model, False, "no laser in the log")
    match = match_scans(scans, log.poses, params)
    # the odometry at the scans' stamps and the matched poses there
    odometry, reference = match.odometry, match.track
    if len(reference) < 2:
        return FileCheck(model, False, "too few scans")
    own = calibrate_tracks(odometry, reference)
    if own is None:
        return FileCheck(model, False, "too little travel")
    dropped = []
    confirmed = set()
    kept = model
    for k, key in enumerate(BIAS_KEYS):
        bias = getattr(model, key)
        value, shown = signed_biases(own)[k]
        se = own.bias_se[k]
        if bias == 0.0 or not shown or not math.isfinite(se):
            continue
        # corrected by the file, this log keeps |value - bias| of bias; uncorrected, |value|
        gain = abs(value) - abs(value - bias)
        if -gain > bias_check.SIGMA * se:
            dropped.append((key, bias, value, se))
            kept = dataclasses.replace(kept, **{key: 0.0, MAGNITUDE_KEYS[k]: 0.0})
        elif gain > bias_check.SIGMA * se:
            confirmed.add(key)
    # each walk no wider than this log's own (its windows against the laser, the scan
    # matcher's jitter taken out), then the walks judged on the positions
    walks = {w: min(getattr(kept, w), getattr(own.model, w)) for w in WALK_KEYS}
    narrowed = tuple(w for w in WALK_KEYS if walks[w] < getattr(kept, w))
    kept = dataclasses.replace(kept, **walks)
    noise = StepNoise.of(kept.random_part())
    # the places the log comes back to, registered scan on scan: the biases judged there
    nodes, _, _, closures, *_ = optimise_with_closures(scans, match, REVISIT_SEARCH)

    def on_revisits_of(m: OdometryError) -> RevisitFactor:
        track = correct_track(odometry, m)
        return revisit_factor(track, nodes, closures, noise, own.jitter_m, own.jitter_rad)

    kept, contradicted, unconfirmed = biases_on_revisits(kept, on_revisits_of, confirmed)
    factor, _ = consistency(
        correct_track(odometry, kept), reference, noise, own.jitter_m, own.jitter_rad,
        own.window_m, own.window_rad,
    )  # fmt: skip
    scale = factor if math.isfinite(factor) and factor < 1.0 else 1.0
    if scale < 1.0:
        kept = dataclasses.replace(kept, **{w: getattr(kept, w) * scale for w in WALK_KEYS})
    # the walks at a map's lengths, on the places the log comes back to
    on_revisits = revisit_factor(
        correct_track(odometry, kept), nodes, closures, StepNoise.of(kept.random_part()),
        own.jitter_m, own.jitter_rad,
    )  # fmt: skip
    cut: tuple[str, ...] = ()
    r = on_revisits.factor
    if math.isfinite(r) and r < 1.0:
        cut = tuple(
            w
            for w, se in zip(WALK_KEYS, own.walk_variance_se, strict=True)
            if getattr(kept, w) > 0.0 and getattr(kept, w) ** 2 < WALK_SIGNIFICANT * se
        )
        kept = dataclasses.replace(kept, **{w: getattr(kept, w) * r for w in cut})
    return FileCheck(
        kept, True, "", tuple(dropped), scale, factor, narrowed,
        on_revisits.revisits, r, cut, contradicted, unconfirmed,
    )  # fmt: skip


def biases_on_revisits(
    model: OdometryError,
    on_revisits: Callable[[OdometryError], RevisitFactor],
    confirmed: Collection[str] = (),
) -> tuple[OdometryError, tuple[tuple[str, int, float], ...], tuple[tuple[str, int, float], ...]]:
    """``model`` without the biases this log's revisits weigh against, and which: those they
    contradict, and those they lean against that the laser does not confirm (each with the
    revisits and their statistic). ``on_revisits`` gives the check on the revisits of a
    model's corrected odometry; ``confirmed``: the biases the log's laser confirms. Each bias
    of the file is a claim about this log; leaving it out is the drift-blind alternative, and
    the revisits (no drift between the two visits) weigh the two at a map's lengths by their
    likelihood ratio (:func:`~.revisit_check.likelihood_ratio`, a chi-square with one degree
    of freedom when the two are worth the same). A bias is not corrected when the track
    without it is the likelier by more than :data:`~.bias_check.SIGMA` standard errors would
    say (the statistic over ``SIGMA**2``), nor when it is the likelier at all and the laser
    does not confirm the bias: a wrong correction turns the whole track; a right one left out
    leaves the track the drift-blind map has. Without revisits (the statistic 0) the bias
    stands. Each bias is judged with those before it decided."""
    contradicted = []
    unconfirmed = []
    base = on_revisits(model)
    for k, key in enumerate(BIAS_KEYS):
        if getattr(model, key) == 0.0:
            continue
        without = dataclasses.replace(model, **{key: 0.0, MAGNITUDE_KEYS[k]: 0.0})
        other = on_revisits(without)
        statistic = likelihood_ratio(base, other)
        if statistic > bias_check.SIGMA**2:
            contradicted.append((key, other.revisits, statistic))
        elif key not in confirmed and statistic > 0.0:
            unconfirmed.append((key, other.revisits, statistic))
        else:
            continue
        model, base = without, other
    return model, tuple(contradicted), tuple(unconfirmed)
