"""What a log can tell of its own map, without ground truth.

Four things, each a check a user can read without a reference:

- **Pose spread** (:func:`spread_summary`): the share of the map's known cells whose readings
  were taken with a position spread within 0.1, 0.5 and 1 m (the layer of
  :func:`~gridmap_cli.evaluation.spread_map.spread_layer`), and from when on the pose spread
  passes each of them (:func:`spread_timeline`). It says how far the map *may* be wrong under
  the pose model it was built with; it cannot see an error the model does not describe.
- **Echo consistency** (:func:`echo_consistency`): the share of a laser's echoes that end in a
  cell the map calls free. Where two passes through a place disagree (the poses drifted
  between them), the second pass's echoes land where the first saw free space, and the map,
  summing both, calls many of those cells free: the share counts how much the map contradicts
  the scans it was built from, with no model and no truth. Sonar echoes are not counted (an
  echo does not say where on its arc it came from).
- **Closure consistency** (:func:`closure_consistency`): a pose graph's loop closures at the
  optimum, each residual whitened by the closure's own covariance (a NEES, chi-square with 3
  degrees of freedom, median 2.37, when the noise is right and the closure true).
- **Revisits** (:mod:`.revisits`): the places the pose graph's closure search found the robot
  back at, each a relative pose registered from the scans; the map's track scored on them (the
  graph's own track on the ones held out of its solve). The echo share is local; this sees a
  map bent or drifted as a whole wherever the robot came back. Numpy only, no file I/O.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import given
from gridmap_cli.evaluation.relation_nees import CHI2_3_MEDIAN, between, log_map
from gridmap_cli.evaluation.revisits import RevisitScore, graph_revisits, map_revisits
from gridmap_cli.mapping.grid import OccupancyMap
from gridmap_cli.mapping.options import BuildOptions
from gridmap_cli.mapping.pipeline import SYNC_CHUNK_READINGS, corrected_for_build
from gridmap_cli.poses.sources import SOURCES, PoseSettings, pose_source
from gridmap_cli.poses.sync import SensorReadings, synchronise
from gridmap_cli.poses.uncertainty.pose_uncertainty import PoseUncertainty, StepNoise, propagate
from gridmap_cli.records import RangeLog, stamps_advance
from gridmap_cli.robot import RobotDescription

if TYPE_CHECKING:
    from gridmap_cli.poses.correction.pose_graph import Edge
    from gridmap_cli.poses.correction.slam import SlamResult

F64 = npt.NDArray[np.float64]
FloatArray = F64

#: Position spreads (metres) the share of the map is reported within: a cell or two, a wall's
#: thickness, a corridor's half width.
SPREAD_THRESHOLDS_M = (0.1, 0.5, 1.0)
#: The spread beyond which the summary says the map stops being usable: half a corridor's width,
#: past which a wall may sit on the other side of the corridor.
USABLE_SPREAD_M = 1.0


def map_log(log: RangeLog, options: BuildOptions) -> tuple[RangeLog, BuildOptions]:
    """The log and options exactly as the build mapped them (the calibrated biases taken out of
    the track when the build corrects the odometry)."""
    if options.correct_odometry:
        return corrected_for_build(log, options)
    return log, options


def map_uncertainty(log: RangeLog, options: BuildOptions) -> PoseUncertainty | None:
    """The pose covariance the map was built with: the pose graph's (its rigid motion taken
    out), or the odometry error carried along the mapped track; None when the build had
    neither (a standard map of odometry or scan matching without an error model)."""
    if options.pose_belief is not None:
        return options.pose_belief.uncertainty
    log, options = map_log(log, options)
    if options.odometry_error is None or len(log.poses) == 0:
        return None
    return propagate(log.poses, StepNoise.of(options.odometry_error))


def map_readings(
    log: RangeLog, robot: RobotDescription | None, options: BuildOptions
) -> Iterator[SensorReadings]:
    """The readings the map was built from, synchronised chunk by chunk in its frame."""
    log, _ = map_log(log, options)
    for chunk in log.reading_chunks(SYNC_CHUNK_READINGS):
        readings, _ = synchronise(log, robot, chunk)
        if len(readings):
            yield readings


@dataclass(frozen=True)
class SpreadSummary:
    """The spread layer in numbers: ``known_cells`` with a spread, its median (metres), the
    share within each of ``thresholds_m``; ``crossing_s``, per threshold, the seconds from the
    log's first pose at which the position spread first passes it (None: never);
    ``duration_s`` the track's span; ``largest_m`` the largest position spread of the track."""

    known_cells: int
    median_m: float
    thresholds_m: tuple[float, ...]
    shares: tuple[float, ...]
    crossing_s: tuple[float | None, ...]
    duration_s: float
    largest_m: float
    #: The same crossings in metres driven from the first pose, and the track's length: what
    #: the summary says when the stamps do not advance (a log whose every record has one stamp).
    crossing_m: tuple[float | None, ...] = ()
    driven_m: float = math.nan
    stamps_advance: bool = True

    def as_dict(self) -> dict[str, Any]:
        def key(t: float) -> str:
            return f"{t:g}"

        return {
            "known_cells": self.known_cells,
            "median_m": _rounded(self.median_m),
            "share_within_m": {
                key(t): round(s, 4) for t, s in zip(self.thresholds_m, self.shares, strict=True)
            },
            "exceeds_after_s": {
                key(t): None if c is None else round(c, 1)
                for t, c in zip(self.thresholds_m, self.crossing_s, strict=True)
            },
            "duration_s": round(self.duration_s, 1),
            "exceeds_after_m": {
                key(t): None if c is None else round(c, 1)
                for t, c in zip(self.thresholds_m, self.crossing_m, strict=True)
            },
            "driven_m": _rounded(self.driven_m),
            "largest_m": _rounded(self.largest_m),
        }

    def when(self, k: int) -> str | None:
        """When the spread passes threshold ``k``: minutes (seconds) from the start, or metres
        driven when the stamps do not advance; None: never."""
        after = self.crossing_s[k]
        if after is None:
            return None
        if self.stamps_advance or k >= len(self.crossing_m):
            return _minutes(after)
        return f"{self.crossing_m[k]:.0f} m driven"

    def span(self) -> str:
        """The track's span in the unit of :meth:`when`."""
        return _minutes(self.duration_s) if self.stamps_advance else f"{self.driven_m:.0f} m"

    def line(self) -> str:
        """Where the map stops being usable, in words (the summary line's part)."""
        usable = self.thresholds_m.index(USABLE_SPREAD_M)
        within = ", ".join(
            f"{100 * s:.0f} % within {t:g} m"
            for t, s in zip(self.thresholds_m, self.shares, strict=True)
        )
        after = self.when(usable)
        if after is None:
            when = (
                f"the position spread stays under {USABLE_SPREAD_M:g} m (largest "
                f"{self.largest_m:.2f} m)"
            )
        else:
            when = (
                f"beyond {after} of {self.span()} the position spread exceeds {USABLE_SPREAD_M:g} m"
            )
        return f"pose spread of the known cells: {within}; {when}"


def _minutes(seconds: float) -> str:
    return f"{seconds / 60:.1f} min" if seconds >= 60 else f"{seconds:.0f} s"


def _rounded(value: float) -> float | None:
    return None if math.isnan(value) else round(value, 4)


def position_spread(cov: F64) -> F64:
    """The position spread (metres, square root of the larger eigenvalue of the x-y block) of
    covariances (K, 3, 3): shape (K,)."""
    a, b, c = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
    largest = 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + b * b)
    out: F64 = np.sqrt(np.maximum(largest, 0.0))
    return out


def spread_timeline(
    uncertainty: PoseUncertainty, thresholds_m: Sequence[float] = SPREAD_THRESHOLDS_M
) -> tuple[tuple[float | None, ...], float, float]:
    """Per threshold, the seconds from the first key pose at which the position spread first
    passes it (None: never); the track's span (s); the largest position spread (m)."""
    if uncertainty.stamp_ns.shape[0] == 0:
        return tuple(None for _ in thresholds_m), 0.0, 0.0
    spread = position_spread(uncertainty.cov)
    seconds = (uncertainty.stamp_ns - uncertainty.stamp_ns[0]).astype(np.float64) * 1e-9
    out: list[float | None] = []
    for t in thresholds_m:
        over = np.flatnonzero(spread > t)
        out.append(float(seconds[over[0]]) if over.size else None)
    return tuple(out), float(seconds[-1]), float(spread.max())


def spread_distances(
    uncertainty: PoseUncertainty, thresholds_m: Sequence[float] = SPREAD_THRESHOLDS_M
) -> tuple[tuple[float | None, ...], float, bool]:
    """Per threshold, the metres driven (along the key poses) at which the position spread
    first passes it (None: never); the track's length; whether its stamps advance (not all
    within :data:`~gridmap_cli.records.MIN_STEP_NS` a key pose)."""
    k = uncertainty.stamp_ns.shape[0]
    if k == 0:
        return tuple(None for _ in thresholds_m), 0.0, True
    steps = np.hypot(np.diff(uncertainty.x_m), np.diff(uncertainty.y_m))
    driven = np.concatenate([[0.0], np.cumsum(steps)])
    spread = position_spread(uncertainty.cov)
    out: list[float | None] = []
    for t in thresholds_m:
        over = np.flatnonzero(spread > t)
        out.append(float(driven[over[0]]) if over.size else None)
    advance = stamps_advance(int(uncertainty.stamp_ns[0]), int(uncertainty.stamp_ns[-1]), k)
    return tuple(out), float(driven[-1]), advance


def spread_summary(
    layer: F64,
    uncertainty: PoseUncertainty,
    thresholds_m: Sequence[float] = SPREAD_THRESHOLDS_M,
) -> SpreadSummary:
    """:class:`SpreadSummary` of a spread layer (NaN where the map knows nothing) and the
    covariance it was drawn from."""
    values = layer[~np.isnan(layer)]
    shares = tuple(float(np.mean(values <= t)) if values.size else 0.0 for t in thresholds_m)
    crossing, duration, largest = spread_timeline(uncertainty, thresholds_m)
    crossing_m, driven, advance = spread_distances(uncertainty, thresholds_m)
    median = float(np.median(values)) if values.size else math.nan
    return SpreadSummary(
        int(values.size), median, tuple(thresholds_m), shares, crossing, duration, largest,
        crossing_m, driven, advance,
    )  # fmt: skip


@dataclass(frozen=True)
class EchoConsistency:
    """Laser echoes looked up in the map at their end: ``echoes`` inside the map's known cells,
    the share of them ending in cells the map calls free (``in_free``, p <= the free
    threshold: the map contradicts them) and occupied (``in_occupied``)."""

    echoes: int
    in_free: float
    in_occupied: float

    def as_dict(self) -> dict[str, Any]:
        return {
            "echoes": self.echoes,
            "in_free": _rounded(self.in_free),
            "in_occupied": _rounded(self.in_occupied),
        }


def echo_consistency(
    omap: OccupancyMap, chunks: Iterator[SensorReadings], occupied: float, free: float
) -> EchoConsistency | None:
    """How many of the laser echoes of ``chunks`` (the map's readings, in its frame) end in
    cells ``omap`` calls free or occupied (the module text). A laser is a sensor whose beam is
    narrow (no beam width); no-echo readings (at the maximum range) are left out. None when no
    laser echo ends in a known cell."""
    spec = omap.spec
    counts = np.zeros(3, dtype=np.int64)  # known, free, occupied
    for readings in chunks:
        beam = readings.per_sensor("beam_width_rad")
        laser = np.array([s.kind == "laser" for s in readings.sensors], dtype=bool)
        narrow = laser[readings.sensor] | (beam <= 0.0)
        echo = narrow & (readings.range_m < readings.per_sensor("max_range_m"))
        if not echo.any():
            continue
        z = readings.range_m[echo]
        x = readings.x_m[echo] + z * np.cos(readings.theta_rad[echo])
        y = readings.y_m[echo] + z * np.sin(readings.theta_rad[echo])
        col, row = spec.world_to_cell(x, y)
        inside = (col >= 0) & (col < spec.width) & (row >= 0) & (row < spec.height)
        p = omap.prob[row[inside], col[inside]]
        p = p[~np.isnan(p)]
        counts += (p.size, int(np.count_nonzero(p <= free)), int(np.count_nonzero(p >= occupied)))
    if counts[0] == 0:
        return None
    return EchoConsistency(int(counts[0]), counts[1] / counts[0], counts[2] / counts[0])


@dataclass(frozen=True)
class ClosureConsistency:
    """A pose graph's loop closures at its optimum: how many, and the median of their NEES
    (``expected_median`` when the closures' noise is right)."""

    closures: int
    median_nees: float
    expected_median: float = CHI2_3_MEDIAN

    def as_dict(self) -> dict[str, Any]:
        return {
            "closures": self.closures,
            "median_nees": _rounded(self.median_nees),
            "expected_median": self.expected_median,
        }


def closure_consistency(poses: F64, edges: Sequence[Edge]) -> ClosureConsistency | None:
    """The loop closures of ``edges`` at ``poses`` (K, 3), the optimum: each residual (the
    optimised relative pose seen from the measured one, as a tangent vector) whitened by the
    closure's covariance. None without a closure."""
    closures = [e for e in edges if e.closure]
    if not closures:
        return None
    values = []
    for e in closures:
        estimated = between(poses[e.i], poses[e.j])
        r = log_map(between(np.array([e.dx_m, e.dy_m, e.dtheta_rad]), estimated))
        values.append(float(r @ np.linalg.solve(e.covariance(), r)))
    return ClosureConsistency(len(closures), float(np.median(values)))


@dataclass(frozen=True)
class Quality:
    """What the log tells of its map (the module text); each part None when it does not apply."""

    spread: SpreadSummary | None
    echoes: EchoConsistency | None
    closures: ClosureConsistency | None
    revisits: RevisitScore | None = None

    def as_dict(self) -> dict[str, Any]:
        return {
            "spread": None if self.spread is None else self.spread.as_dict(),
            "echo_consistency": None if self.echoes is None else self.echoes.as_dict(),
            "closures": None if self.closures is None else self.closures.as_dict(),
            "revisits": None if self.revisits is None else self.revisits.as_dict(),
        }


def map_spread(
    log: RangeLog, robot: RobotDescription | None, options: BuildOptions, omap: OccupancyMap
) -> tuple[F64, PoseUncertainty] | None:
    """The pose-spread layer of a map built from ``log`` with ``options`` (the covariance of
    :func:`map_uncertainty`, the readings of :func:`map_readings`) on its grid, NaN where the
    map knows nothing, and the covariance; None without one."""
    from gridmap_cli.evaluation.spread_map import spread_layer

    uncertainty = map_uncertainty(log, options)
    if uncertainty is None:
        return None
    known = ~np.isnan(omap.prob)
    return spread_layer(
        omap.spec, map_readings(log, robot, options), uncertainty, known
    ), uncertainty


def map_quality(
    log: RangeLog,
    robot: RobotDescription | None,
    options: BuildOptions,
    omap: OccupancyMap,
    thresholds: tuple[float, float],
    spread: tuple[F64, PoseUncertainty] | None = None,
    graph: tuple[F64, Sequence[Edge]] | None = None,
    echoes: bool = True,
    revisits: RevisitScore | None = None,
) -> Quality:
    """Everything :class:`Quality` holds for a map built from ``log`` with ``options``:
    ``thresholds`` (occupied, free) classify its cells; ``spread`` from :func:`map_spread`;
    ``graph`` the pose graph's optimum and edges (a pose graph's build); ``echoes`` False
    leaves out the echo consistency (a pass over the readings); ``revisits`` from
    :func:`track_revisits`."""
    occupied, free = thresholds
    consistency = None
    if echoes and has_laser(log, robot):
        consistency = echo_consistency(omap, map_readings(log, robot, options), occupied, free)
    return Quality(
        spread=None if spread is None else spread_summary(*spread),
        echoes=consistency,
        closures=None if graph is None else closure_consistency(*graph),
        revisits=revisits,
    )


def track_revisits(
    slam: SlamResult, graph_log: RangeLog, robot: RobotDescription | None, mapped: RangeLog,
    graph_track: bool,
) -> RevisitScore | None:  # fmt: skip
    """The track of ``mapped`` (the log as mapped) scored on the revisits ``slam`` found in
    ``graph_log`` (the log its graph was solved from); ``graph_track``: the map's track is the
    graph's own, so it is scored on the closures held out of its solve. None without a
    closure."""
    revisits = graph_revisits(slam, graph_log, robot, hold_out=graph_track)
    return map_revisits(revisits, mapped.poses, graph_track)


def has_laser(log: RangeLog, robot: RobotDescription | None) -> bool:
    """Whether ``log`` holds laser scans (what the scan-matching pose sources map from)."""
    from gridmap_cli.poses.sync import sensors_for_log

    return any(s.kind == "laser" for s in sensors_for_log(log, robot))


def quality_notes(
    quality: Quality, pose: str, log: RangeLog, robot: RobotDescription | None
) -> list[str]:
    """The summary's words on the map's quality: where it stops being usable, and, for an
    odometry map of a laser log whose spread passes :data:`USABLE_SPREAD_M`, the pose source
    that would map it (``pose``: the map's source's name)."""
    if quality.spread is None:
        return []
    notes = [quality.spread.line()]
    usable = quality.spread.thresholds_m.index(USABLE_SPREAD_M)
    lost = quality.spread.crossing_s[usable] is not None
    if lost and "odometry" in pose_source(pose).needs and has_laser(log, robot):
        notes.append(f"the log has a laser: {given('pose', _graph_source())} corrects the poses "
                     "from its scans")  # fmt: skip
    return notes


def _graph_source() -> str:
    """The pose source that corrects the poses from the scans and knows its uncertainty."""
    return next(s.name for s in SOURCES if s.belief and "laser" in s.needs)


def log_quality(
    omap: OccupancyMap,
    log: RangeLog,
    robot: RobotDescription | None,
    pose: str,
    options: BuildOptions,
    thresholds: tuple[float, float],
) -> Quality:
    """The :class:`Quality` of a map read back from its file (``gridmap evaluate MAP --log
    LOG``): ``log`` posed as the map was built (``pose``: a source of
    :data:`~gridmap_cli.poses.sources.SOURCES`; a pose graph's is built again and gives the
    spread and the closures), ``options`` the odometry error the spread is carried with (or
    none). The map must be the one built from ``log`` with ``pose``: its frame is the
    track's. A log with a laser is also posed by the pose graph, when ``pose`` did not, for
    the revisits its track is scored on."""
    posed = pose_source(pose).run(log, robot, PoseSettings(belief_samples=0))
    graph = None
    if posed.belief is not None:
        options = dataclasses.replace(options, pose_belief=posed.belief)
    if posed.slam is not None and posed.slam.graph is not None:
        graph = (posed.slam.poses, posed.slam.graph.edges)
    revisits = None
    if posed.slam is not None:
        # the map's track is the graph's own when the source kept the graph's match
        own = posed.match is posed.slam.match
        revisits = track_revisits(posed.slam, posed.log, robot, posed.log, own)
    elif has_laser(log, robot):
        found = pose_source(_graph_source()).run(log, robot, PoseSettings())
        if found.slam is not None:
            revisits = track_revisits(found.slam, found.log, robot, posed.log, False)
    spread = map_spread(posed.log, robot, options, omap)
    return map_quality(posed.log, robot, options, omap, thresholds, spread, graph,
                       revisits=revisits)  # fmt: skip


def quality_table(map_name: str, log_name: str, pose: str, quality: Quality) -> str:
    """``gridmap evaluate MAP --log LOG``'s table: the quality in words and numbers."""
    lines = [f"{map_name} judged by {log_name} ({given('pose', pose)}), without ground truth", ""]
    s = quality.spread
    if s is None:
        lines.append(f"pose spread           n/a (give {given('odometry_error', 'FILE')}, or "
                     f"{given('pose', _graph_source())})")  # fmt: skip
    else:
        lines.append(
            f"pose spread           median {s.median_m:.3f} m over {s.known_cells:,} known cells"
        )
        for k, (t, share) in enumerate(zip(s.thresholds_m, s.shares, strict=True)):
            after = s.when(k)
            when = "never passed" if after is None else f"passed after {after}"
            lines.append(f"  within {t:g} m{'':<7s}{100 * share:5.1f} % of the cells ({when})")
    e = quality.echoes
    if e is None:
        lines.append("echo consistency      n/a (no laser echo inside the map)")
    else:
        lines.append(
            f"echo consistency      {100 * e.in_free:.2f} % of {e.echoes:,} laser echoes end in "
            f"cells the map calls free (lower is better), {100 * e.in_occupied:.1f} % in occupied"
        )
    v = quality.revisits
    if v is None:
        lines.append("revisits              n/a (no loop closed, or no laser)")
    else:
        how = "held out of the graph's solve" if v.held_out else "the map's track"
        lines.append(
            f"revisits              {v.relations:,} places the scans found twice ({how}): "
            f"mean {v.mean_m:.3f} m between the two visits' echoes (lower is better), median "
            f"{v.median_m:.3f} m, mean {v.rot_mean_deg:.2f} deg"
        )
    c = quality.closures
    if c is not None:
        lines.append(
            f"loop closures         {c.closures:,}, median NEES {c.median_nees:.2f} (a consistent "
            f"graph: {c.expected_median:.2f}; larger: the closures disagree more than their noise)"
        )
    return "\n".join(lines)
