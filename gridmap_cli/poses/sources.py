"""The pose sources a map can be built with, in one table: :data:`SOURCES`.

Each source says what it needs of a log (odometry, a laser, a reference track), in which frame
its track lies, its help text, and where its function is (``module:function``, imported only
when the source is used: the pose graph pulls in gtsam). The function takes the log, the robot
and :class:`PoseSettings` and returns a :class:`PosedLog`: the log with the chosen poses and what
the source learnt on the way (the scan match, the pose graph, its belief, summary fields,
warnings). The commands' ``--pose`` choices, help texts and "this log cannot do that" errors
read the table; nothing else compares a source's name.

A new source is one module holding its function and one :class:`PoseSource` line below.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from gridmap_cli.errors import InputFileError, UsageError, given, naming_style
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RobotDescription

if TYPE_CHECKING:
    from gridmap_cli.poses.correction.free_space import FreeSpaceCheck
    from gridmap_cli.poses.correction.scan_match import ScanMatch
    from gridmap_cli.poses.correction.slam import SlamResult
    from gridmap_cli.poses.uncertainty.pose_belief import PoseBelief

#: What a source may need of a log: the robot's own odometry (a log whose pose track is not
#: one, such as a corrected CARMEN log's, cannot be mapped by it), laser scans, a reference.
NEEDS = ("odometry", "laser", "reference")
#: Called with a stage's name, its done and total counts (the CLI's progress bars).
Progress = Callable[[str, int, int], object]


@dataclass(frozen=True)
class PoseSettings:
    """How a source is run: ``progress`` for the long stages; ``belief_samples`` not None asks
    a source that knows its uncertainty (the pose graph) for its belief with that many draws,
    seeded by ``belief_seed``."""

    progress: Progress | None = None
    belief_samples: int | None = None
    belief_seed: int = 0
    #: the build was given the odometry's error model: a source that chooses maps the odometry,
    #: which that model describes
    odometry_model: bool = False


@dataclass(frozen=True)
class PosedLog:
    """A log placed by a pose source, and what the source learnt.

    ``log``: the log with its poses replaced by the source's track (at the odometry's stamps);
    ``match``: the scan match (scan-matched, and slam's optimised one); ``slam``: the pose
    graph's result; ``belief``: the pose graph's belief when asked; ``summary``: fields for a
    report, by section (``{"slam": {...}}``); ``warnings``: what the user should read.
    """

    log: RangeLog
    source: str
    match: ScanMatch | None = None
    slam: SlamResult | None = None
    belief: PoseBelief | None = None
    summary: Mapping[str, Mapping[str, object]] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    #: where the track's motion came from when the log had no odometry (None: its odometry)
    motion: str | None = None
    #: the pose graph's track checked against its scans where the robot came back
    free_space: FreeSpaceCheck | None = None


Runner = Callable[[RangeLog, RobotDescription | None, PoseSettings], PosedLog]


@dataclass(frozen=True)
class PoseSource:
    """One way to place a log's readings.

    ``needs``: what of :data:`NEEDS` the log must hold; ``frame``: "odometry" (the track starts
    where the odometry does) or "world" (the reference's frame); ``help``: a phrase for the
    commands' help (what the track is); ``runner``: ``module:function`` of its
    :data:`Runner`; ``belief``: the source knows its own uncertainty (a pose graph's), so an
    error-aware map of it needs no odometry-error model; ``scans``: the source may read the
    laser's scans, so the log's readings are held for it (None: when it needs a laser; a
    source that chooses by the log, falling back where there is no laser, sets True)."""

    name: str
    needs: frozenset[str]
    frame: str
    help: str
    runner: str
    belief: bool = False
    scans: bool | None = None

    @property
    def chooses(self) -> bool:
        """True for a source that picks another by what the log holds (it needs nothing of
        its own and may read the scans)."""
        return not self.needs and bool(self.scans)

    @property
    def uses_laser(self) -> bool:
        """True when the source may read the laser: the log's readings are held for it."""
        return "laser" in self.needs if self.scans is None else self.scans

    def run(
        self, log: RangeLog, robot: RobotDescription | None, settings: PoseSettings | None = None
    ) -> PosedLog:
        """``log`` placed by this source; raises :class:`GridmapError` when the log lacks what
        the source needs."""
        check_needs(self, log, robot)
        module, _, function = self.runner.partition(":")
        run: Runner = getattr(importlib.import_module(module), function)
        return run(log, robot, settings or PoseSettings())


SOURCES: tuple[PoseSource, ...] = (
    PoseSource("odometry", frozenset({"odometry"}), "odometry", "the robot's wheel odometry",
               "gridmap_cli.poses.sources:odometry_poses"),
    PoseSource("global", frozenset({"reference"}), "world",
               "the log's reference track: ARIA robotGlobal, CSV true_*, CARMEN's corrected poses "
               "or TRUEPOS, a ROS recording's TF map -> base or --pose-topic",
               "gridmap_cli.poses.sources:global_poses"),
    PoseSource("scan-matched", frozenset({"laser"}), "odometry",
               "the odometry corrected by matching the laser scans",
               "gridmap_cli.poses.sources:scan_matched_poses"),
    PoseSource("slam", frozenset({"laser"}), "odometry",
               "the scan-matched track with loop closures on a pose graph",
               "gridmap_cli.poses.sources:slam_poses", belief=True),
    PoseSource("auto", frozenset(), "odometry",
               "the best the log allows: slam where it has a laser, the odometry otherwise; a "
               "slam track that fails its own checks falls back to scan-matched or the odometry, "
               "with a warning",
               "gridmap_cli.poses.sources:auto_poses", belief=True, scans=True),
)  # fmt: skip
#: The source a map or a track is made with when none is named.
DEFAULT_SOURCE = "auto"
#: The source that calibrates: the robot's own odometry.
ODOMETRY_SOURCE = "odometry"
#: A scan match that fell back to the odometry on more than this share of its scans did not
#: match the laser: when slam fails its checks, the fallback is then the odometry itself.
MATCHED_SHARE_MIN = 0.5


def source_names(needs_not: str | None = None) -> tuple[str, ...]:
    """The sources' names, in the table's order; ``needs_not``: only those that do not need
    that and make their own track (``source_names(needs_not="laser")``)."""
    if needs_not is None:
        return tuple(s.name for s in SOURCES)
    return tuple(s.name for s in SOURCES if needs_not not in s.needs and not s.chooses)


def pose_source(name: str) -> PoseSource:
    """The source called ``name``; :class:`UsageError` naming the known ones otherwise."""
    for source in SOURCES:
        if source.name == name:
            return source
    raise UsageError(f"unknown pose source '{name}' (known: {', '.join(source_names())})")


def check_needs(source: PoseSource, log: RangeLog, robot: RobotDescription | None) -> None:
    """Raise the error of a log that lacks what ``source`` needs: odometry a map could be
    built with, a reference track, laser scans."""
    if source.chooses:
        if not has_laser(log, robot) and (log.odometry_missing is None or log.truth is None):
            check_needs(pose_source(ODOMETRY_SOURCE), log, robot)
        return
    if "odometry" in source.needs and log.odometry_missing is not None:
        raise InputFileError(log.source, f"{given('pose', source.name)}: odometry "
                                         f"{log.odometry_missing}")  # fmt: skip
    if "reference" in source.needs:
        log.require_truth(f"{given('pose', source.name)} maps with it")
    if "laser" in source.needs:
        from gridmap_cli.poses.correction.scan_match import NoLaserError
        from gridmap_cli.poses.sync import sensors_for_log

        kinds = sorted({s.kind for s in sensors_for_log(log, robot)}) or ["none"]
        if "laser" not in kinds:
            others = source_names(needs_not="laser")
            if naming_style() == "flags":
                use = given("pose", " or ".join(others))
            else:
                use = " or ".join(given("pose", name) for name in others)
            raise NoLaserError(
                f"{log.source}: {given('pose', source.name)} matches laser scans, and the log "
                f"has no laser (its range sensors: {', '.join(kinds)}); use {use}"
            )


def odometry_poses(
    log: RangeLog, robot: RobotDescription | None, settings: PoseSettings
) -> PosedLog:
    """The robot's own odometry, as the log holds it."""
    return PosedLog(log, "odometry")


def global_poses(log: RangeLog, robot: RobotDescription | None, settings: PoseSettings) -> PosedLog:
    """The log's reference track: a corrected pose or ground truth, in the world's frame."""
    truth = log.require_truth(f"{given('pose', 'global')} maps with it")
    return PosedLog(dataclasses.replace(log, poses=truth), "global")


def scan_matched_poses(
    log: RangeLog, robot: RobotDescription | None, settings: PoseSettings
) -> PosedLog:
    """The odometry corrected by registering each laser scan against the ones before it."""
    from gridmap_cli.poses.correction.scan_match import scan_matched_log  # scipy, small_gicp

    log, motion, warnings = _scan_motion(log, robot, settings, "scan-matched")
    placed, match = scan_matched_log(log, robot, progress=settings.progress)
    summary: dict[str, object] = dict(match.summary())
    mounting = None if motion else _mount_check(log, robot, match, summary, "scan-matched")
    return PosedLog(placed, "scan-matched", match=match, summary={"scan_match": summary},
                    warnings=(*warnings, *filter(None, [mounting])), motion=motion)  # fmt: skip


def slam_poses(log: RangeLog, robot: RobotDescription | None, settings: PoseSettings) -> PosedLog:
    """The scan-matched track with loop closures, optimised as a pose graph; with its belief
    when ``settings`` asks for it."""
    from gridmap_cli.poses.correction.slam import slam_corrected_log  # gtsam: only here

    log, motion, early = _scan_motion(log, robot, settings, "slam")
    placed, slam = slam_corrected_log(log, robot, progress=settings.progress)
    summary = slam.summary()
    belief = None
    if settings.belief_samples is not None:
        from gridmap_cli.poses.uncertainty.pose_belief import slam_belief

        belief = slam_belief(slam, settings.belief_samples, settings.belief_seed)
        summary["belief_noise_scale"] = [round(f, 3) for f in belief.scale]
    warnings = [*early, *([f"{given('pose', 'slam')}: {slam.warning}"] if slam.warning else [])]
    mounting = None if motion else _mount_check(log, robot, slam.match, summary, "slam")
    warnings.extend(filter(None, [mounting]))
    check = None
    if slam.scans is not None:
        from gridmap_cli.poses.correction.free_space import verdict

        # the graph's own check of this track (the same scans and poses), then the wide look
        check, wide, said = verdict(slam.track, slam.scans.points, slam.free_space)
        summary["free_space_check"] = check.as_dict()
        if wide is not None:
            summary["free_space_check_wide"] = wide.as_dict()
        if said is not None:
            warnings.append(f"{given('pose', 'slam')}: {said}; check the map")
    return PosedLog(placed, "slam", match=slam.match, slam=slam, belief=belief,
                    summary={"slam": summary}, warnings=tuple(warnings), motion=motion,
                    free_space=check)  # fmt: skip


def _scan_motion(
    log: RangeLog, robot: RobotDescription | None, settings: PoseSettings, source: str
) -> tuple[RangeLog, str | None, tuple[str, ...]]:
    """``log`` as the scan matcher takes it: a log read without odometry (a hand-held laser)
    gets a track chained from its scans, the note that says so, and the warning of scans too
    far apart for such a track (:func:`.scan_odometry.far_apart`, for the pose ``source``);
    any other log as it is."""
    if log.odometry_missing is None or len(log.poses):
        return log, None, ()
    from gridmap_cli.poses.correction.scan_odometry import MOTION_NOTE, far_apart, with_scan_motion

    moving = with_scan_motion(log, robot, progress=settings.progress)
    warning = far_apart(moving.poses)
    return moving, MOTION_NOTE, () if warning is None else (f"{given('pose', source)}: {warning}",)


def auto_poses(log: RangeLog, robot: RobotDescription | None, settings: PoseSettings) -> PosedLog:
    """The best source the log allows: the pose graph where there is a laser, else the robot's
    odometry (a log without odometry but with a reference track: the reference, with a
    warning). A slam track that fails its own checks (no loop closed is no failure: the track
    is then the scan-matched one) falls back to the scan-matched track, or to the odometry when
    the scan matcher itself mostly fell back to it; the warning says why."""
    if settings.odometry_model and log.odometry_missing is None:
        posed = odometry_poses(log, robot, settings)
        return _chosen(posed, "odometry", "an odometry-error model was given")
    if not has_laser(log, robot):
        if log.odometry_missing is not None and log.truth is not None:
            posed = global_poses(log, robot, settings)
            why = (
                f"{given('pose', 'auto')}: the log has no odometry ({log.odometry_missing}) and "
                "no laser: mapped with its reference track"
            )
            return _chosen(posed, "global", "no laser, no odometry", (why,))
        check_needs(pose_source("odometry"), log, robot)
        return _chosen(odometry_poses(log, robot, settings), "odometry", "no laser")
    # the motion from the scans made once, here: a fallback from the graph's track needs it too
    log, motion, early = _scan_motion(log, robot, settings, "auto")
    chosen = _laser_choice(log, robot, settings)
    return dataclasses.replace(chosen, warnings=(*early, *chosen.warnings), motion=motion)


def _laser_choice(
    log: RangeLog, robot: RobotDescription | None, settings: PoseSettings
) -> PosedLog:
    """The automatic choice for a log with a laser and a track to correct (see
    :func:`auto_poses`)."""
    posed = slam_poses(log, robot, settings)
    slam = posed.slam
    assert slam is not None
    failed = graph_failure(slam)
    if failed is None:
        if posed.free_space is not None and posed.free_space.fails:
            return _free_space_fallback(log, robot, settings, posed)
        return _chosen(posed, "slam", "a laser", posed.warnings)
    matched = slam.scan_matched
    scans = max(len(matched.status), 1)
    if matched.fallbacks / scans > MATCHED_SHARE_MIN and log.odometry_missing is None:
        name = "odometry"
        detail = (
            f"the scan matcher fell back to the odometry on {matched.fallbacks} of {scans} scans"
        )
    else:
        name, detail = "scan-matched", "the scan-matched track has no closure to be wrong"
    fallback = _fallback(log, robot, settings, slam, name)
    why = (f"{given('pose', 'auto')}: the pose graph failed its own check ({failed}); "
           f"mapped with the {name} track instead ({detail}); {given('pose', 'slam')} maps "
           "with the graph anyway")  # fmt: skip
    summary = {**fallback.summary, "slam": posed.summary.get("slam", {})}
    fallback = dataclasses.replace(fallback, summary=summary)
    return _chosen(fallback, name, "the pose graph failed its check", (why,))


def _fallback(
    log: RangeLog, robot: RobotDescription | None, settings: PoseSettings, slam: SlamResult,
    name: str,
) -> PosedLog:  # fmt: skip
    """The log placed by the graph's own scan match (``name`` "scan-matched") or the odometry."""
    if name == "odometry":
        return odometry_poses(log, robot, settings)
    from gridmap_cli.poses.correction.scan_match import corrected_track

    matched = slam.scan_matched
    placed = dataclasses.replace(log, poses=corrected_track(log.poses, matched))
    return PosedLog(placed, "scan-matched", match=matched,
                    summary={"scan_match": matched.summary()})  # fmt: skip


def _free_space_fallback(
    log: RangeLog, robot: RobotDescription | None, settings: PoseSettings, posed: PosedLog
) -> PosedLog:
    """The automatic choice when the graph's track fails its free-space check: the scan-matched
    track or the odometry, whichever contradicts itself at fewer of its revisits, when it does
    so at fewer than the graph's track and brings at least half as many places back together
    (a track that brings fewer avoids the check by missing loops, not by agreeing); else the
    graph's track, with the warning."""
    from gridmap_cli.poses.correction.free_space import check_poses, judged_together

    slam, own = posed.slam, posed.free_space
    assert slam is not None and slam.scans is not None and own is not None
    tracks = {"scan-matched": slam.scan_matched.track}
    if log.odometry_missing is None:
        tracks["odometry"] = slam.scan_matched.odometry
    checks = judged_together(
        {"slam": own} | {n: check_poses(t, slam.scans.points) for n, t in tracks.items()}
    )
    graph = checks["slam"]
    better = [n for n in tracks if checks[n].revisits >= graph.revisits / 2
              and checks[n].share < graph.share]  # fmt: skip
    summary = {**posed.summary, "free_space_check": {n: c.as_dict() for n, c in checks.items()}}
    figures = ", ".join(f"{n} {c.contradicting} of {c.revisits}" for n, c in checks.items())
    head = f"{given('pose', 'auto')}: the pose graph's track fails its free-space check: "
    if not better:
        why = (f"{head}{graph.reason()}; kept it, no other track does better (contradicting "
               f"places: {figures}); check the map")  # fmt: skip
        kept = dataclasses.replace(posed, summary=summary)
        also = (f"{given('pose', 'slam')}: {slam.warning}",) if slam.warning else ()
        return _chosen(kept, "slam", "a laser; no other track did better", (why, *also))
    name = min(better, key=lambda n: checks[n].share)
    fallback = _fallback(log, robot, settings, slam, name)
    why = (f"{head}{graph.reason()}; mapped with the {name} track instead (contradicting "
           f"places: {figures}); {given('pose', 'slam')} maps with the graph anyway")  # fmt: skip
    fallback = dataclasses.replace(fallback, summary={**fallback.summary, **summary})
    return _chosen(fallback, name, "the pose graph's track failed its free-space check", (why,))


def graph_failure(slam: SlamResult) -> str | None:
    """Why the automatic choice does not trust a pose graph: its optimum fits its own closures
    no better than the odometry does. No loop closed is no failure (the track is then the
    scan-matched one, and the graph's warning says so), and a bend of the scan-matched track is
    warned of but not acted on: a true closure after a long drift bends it as much."""
    if slam.closures and slam.residual_m >= slam.odometry_residual_m:
        return (
            f"the optimised track fits its loop closures no better than the odometry "
            f"({slam.residual_m:.3f} m against {slam.odometry_residual_m:.3f} m)"
        )
    return None


def _mount_check(
    log: RangeLog,
    robot: RobotDescription | None,
    match: ScanMatch,
    summary: dict[str, object],
    source: str,
) -> str | None:
    """The laser's mounting checked against the odometry's turns (:mod:`.laser_mount`), into
    ``summary["laser_mount"]``; the warning when they disagree. Only for a log with one laser
    mounting and its own odometry (a track chained from the scans has no lever to measure)."""
    from gridmap_cli.poses.laser_mount import check_match

    check = check_match(log, robot, match)
    if check is None:
        return None
    summary["laser_mount"] = check.as_dict()
    return f"{given('pose', source)}: {check.reason()}" if check.disagrees else None


def has_laser(log: RangeLog, robot: RobotDescription | None) -> bool:
    """True when the log holds readings of a laser whose geometry is known (a sensor no robot
    describes cannot be matched: the odometry then needs no robot)."""
    from gridmap_cli.errors import GridmapError
    from gridmap_cli.poses.sync import sensors_for_log

    if log.reading_count == 0:
        return False
    try:
        return any(s.kind == "laser" for s in sensors_for_log(log, robot))
    except GridmapError:
        return False


def _chosen(posed: PosedLog, name: str, reason: str, warnings: tuple[str, ...] = ()) -> PosedLog:
    """``posed`` as the automatic choice made it: its summary names the source and why."""
    summary = {**posed.summary, "pose_choice": {"source": name, "because": reason}}
    return dataclasses.replace(posed, source=name, summary=summary, warnings=warnings)


def pose_help(intro: str) -> str:
    """``intro`` and each source's name and help phrase, for a command's ``--pose``."""
    phrases = [f"{s.name} ({s.help})" for s in SOURCES]
    return f"{intro} {', '.join(phrases[:-1])}, or {phrases[-1]}."
