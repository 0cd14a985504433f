"""One map from a request: the build flow written once.

:func:`build` takes a :class:`BuildRequest` (the logs to read or a log already read, the robot,
the map options, the pose source, the part of the log) and returns a :class:`MapBuild` (the map,
the track it was built with and its uncertainty, summary fields, warnings). It prints nothing,
writes no file and knows no command line: ``gridmap build``, ``batch``, the Python API and the
tests call it alike, and :func:`pose_stage` (its pose stage: read, robot, pose source, selection) is
what ``--fuse`` maps partial grids from.

Callers that show progress or hand memory back pass :class:`BuildHooks`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from gridmap_cli.errors import GridmapError, UsageError, given
from gridmap_cli.mapping.options import BuildOptions, BuildResult
from gridmap_cli.mapping.selection import Selection
from gridmap_cli.poses.sources import (
    DEFAULT_SOURCE,
    SOURCES,
    PosedLog,
    PoseSettings,
    has_laser,
    pose_source,
)
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import RobotDescription

if TYPE_CHECKING:
    from gridmap_cli.evaluation.quality import FloatArray, Quality
    from gridmap_cli.mapping.grid import OccupancyMap
    from gridmap_cli.poses.uncertainty.pose_belief import PoseBelief
    from gridmap_cli.poses.uncertainty.pose_uncertainty import PoseUncertainty

#: Reads logs: (paths, format name or None, options) -> one log.
Reader = Callable[[Sequence[Path], str | None, ReadOptions], RangeLog]


@dataclass(frozen=True)
class BuildRequest:
    """What to map and how.

    ``inputs``: logs to read as one (several ROS recordings are merged by time), or ``log``: a
    log already read (one of the two). ``robot``: a description, or a preset name or file to
    load; None takes the log's own ``# robot:`` line. ``options``: the map options, checked
    (:func:`gridmap_cli.runs.settings.map_settings`). ``pose``: a pose source's name
    (:data:`gridmap_cli.poses.sources.SOURCES`). ``selection``: the sensors and time window to
    map. ``initial_pose``: where the track's first pose is in a common frame (x_m, y_m, yaw_rad),
    for logs mapped together. ``keep_tracks``: keep the log's reference track beside the
    chosen one (to draw them); else it is let go before mapping. ``stream``: a long log's
    readings may stay in its file, read again at each pass, when nothing needs them held.
    """

    inputs: tuple[Path, ...] = ()
    log: RangeLog | None = None
    robot: RobotDescription | str | None = None
    options: BuildOptions = field(default_factory=BuildOptions)
    pose: str = DEFAULT_SOURCE
    selection: Selection = field(default_factory=Selection)
    log_format: str | None = None
    read_options: ReadOptions = field(default_factory=ReadOptions)
    initial_pose: tuple[float, float, float] | None = None
    keep_tracks: bool = False
    stream: bool = True


@dataclass(frozen=True)
class BuildHooks:
    """How a caller follows a build: ``read`` reads the inputs (standard input, hints of its
    own); ``reading`` wraps the read (a spinner); ``stages`` gets the pose source's
    ``(stage, done, total)``; ``mapped`` the readings just mapped; ``between_passes`` is
    called before the mapping pass; ``warn`` gets each warning as it arises."""

    read: Reader | None = None
    reading: Callable[[], AbstractContextManager[object]] | None = None
    stages: Callable[[str, int, int], object] | None = None
    mapped: Callable[[int], object] | None = None
    between_passes: Callable[[], object] | None = None
    warn: Callable[[str], object] | None = None


@dataclass(frozen=True)
class Placed:
    """A log placed by its pose source and cut to the request's selection: ``log`` is what is
    mapped; ``read`` the log as read, with its own tracks (odometry, reference), when the
    request keeps them; ``posed`` what the pose source gave; ``robot`` the description used;
    ``read_s`` the seconds of the stage."""

    log: RangeLog
    read: RangeLog | None
    posed: PosedLog
    robot: RobotDescription | None
    warnings: tuple[str, ...]
    read_s: float


@dataclass(frozen=True)
class MapBuild:
    """A built map and what went into it.

    ``map``: the grid (probabilities, NaN unknown) and its placement; ``poses``: the track it
    was built with; ``belief``: the pose graph's belief about it, when the pose source has one
    (its marginals; draws too for an error-aware map); ``options``: the map options used;
    ``stats``: readings and cell updates; ``summary``: fields for a report (the pose source's,
    ``odometry_corrected``); ``warnings``: what the user should read; ``seconds``: "read"
    (read, poses, selection) and "map"."""

    map: OccupancyMap
    placed: Placed
    options: BuildOptions
    stats: BuildResult
    summary: dict[str, object]
    warnings: tuple[str, ...]
    seconds: dict[str, float]

    @property
    def poses(self) -> PoseTrack:
        return self.placed.log.poses

    @property
    def log(self) -> RangeLog:
        return self.placed.log

    @property
    def belief(self) -> PoseBelief | None:
        return self.placed.posed.belief

    def uncertainty(self) -> PoseUncertainty | None:
        """The covariance of each pose of :attr:`poses`: the pose graph's, or the odometry
        error carried along the track; None without either."""
        if self.belief is not None:
            return self.belief.uncertainty
        if self.options.odometry_error is None:
            return None
        from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise, propagate

        return propagate(self.poses, StepNoise.of(self.options.odometry_error))

    def spread(self) -> tuple[FloatArray, PoseUncertainty] | None:
        """The pose-spread layer of a map that knows its poses' uncertainty
        (:func:`has_spread_layer`): per cell of :attr:`map`, the position spread of the readings
        that crossed it (metres, NaN where the map knows nothing), and the covariance it was
        drawn from; None for another map."""
        if not has_spread_layer(self.options, self.placed.posed.source):
            return None
        from gridmap_cli.evaluation.quality import map_spread

        return map_spread(self.log, self.placed.robot, self._judged(), self.map)

    def quality(
        self,
        thresholds: tuple[float, float],
        spread: tuple[FloatArray, PoseUncertainty] | None = None,
        echoes: bool = True,
        revisits: bool = True,
    ) -> Quality:
        """What the log tells of the map, without ground truth: ``thresholds`` (occupied, free)
        classify its cells; ``spread`` from :meth:`spread`; the pose graph's closures, and
        the map's track on the revisits they found, when the source built one; ``echoes``
        False leaves out the echo consistency (a pass over the readings), ``revisits`` False
        the revisits (a pass over the laser's readings and a few more solves of the graph)."""
        from gridmap_cli.evaluation.quality import map_quality, track_revisits

        posed = self.placed.posed
        slam = posed.slam
        graph = None if slam is None or slam.graph is None else (slam.poses, slam.graph.edges)
        score = None
        if revisits and slam is not None:
            # the map's track is the graph's own when the source kept the graph's match
            own = posed.match is slam.match
            score = track_revisits(slam, posed.log, self.placed.robot, self.log, own)
        return map_quality(self.log, self.placed.robot, self._judged(), self.map, thresholds,
                           spread, graph, echoes, score)  # fmt: skip

    def _judged(self) -> BuildOptions:
        """The options with the pose source's belief, which a standard map is not built with
        but its spread is drawn from."""
        return dataclasses.replace(self.options, pose_belief=self.belief)


def has_spread_layer(options: BuildOptions, pose: str) -> bool:
    """Whether a map built with ``options`` by the pose source ``pose`` knows its poses'
    uncertainty, so a pose-spread layer goes beside it: an error-aware map, or a map of a source
    that knows its own (a pose graph)."""
    return options.mode == "error-aware" or pose_source(pose).belief


def pose_stage(request: BuildRequest, hooks: BuildHooks | None = None) -> Placed:
    """The pose stage of :func:`build`: the log read (or taken), its robot, placed by the pose
    source, moved to ``initial_pose`` and cut to the selection. Raises :class:`GridmapError`
    for a log the source cannot place or a selection that leaves nothing."""
    from gridmap_cli.mapping.selection import apply_selection

    hooks = hooks or BuildHooks()
    started = time.perf_counter()
    source = pose_source(request.pose)
    robot = _robot(request.robot)
    # a source that chooses by the log reads it as a sonar log is read (a long one left in its
    # file), and again, held, when it turns out to hold a laser's scans
    whole = _read(request, source.uses_laser and not source.chooses, robot, hooks)
    if robot is None:
        robot = robot_of(whole, request.inputs)
    if source.chooses and whole.stream is not None and has_laser(whole, robot):
        whole = _read(request, True, robot, hooks)
    mode = request.options.mode
    settings = PoseSettings(  # the belief's marginals (the spread) and, error-aware, its draws
        progress=hooks.stages,
        belief_samples=request.options.error_samples if mode == "error-aware" else 0,
        belief_seed=request.options.error_seed,
        odometry_model=request.options.odometry_error_given,
    )
    posed = source.run(whole, robot, settings)
    warnings = list(posed.warnings)
    for warning in warnings:
        _say(hooks, warning)
    data = posed.log
    if request.initial_pose is not None:
        data = dataclasses.replace(data, poses=move_track(data.poses, request.initial_pose))
    note = _reference_note(request)
    if note is not None:
        warnings.append(note)
        _say(hooks, note)
    if not request.keep_tracks:  # the other tracks are drawn only; let them go
        data = dataclasses.replace(data, truth=None)
    selected = apply_selection(data, request.selection, robot)
    for notice in selected.notes:
        _say(hooks, notice)
    warnings.extend(selected.notes)
    return Placed(selected.log, whole if request.keep_tracks else None, posed, robot,
                  tuple(warnings),
                  time.perf_counter() - started)  # fmt: skip


def build(request: BuildRequest, hooks: BuildHooks | None = None) -> MapBuild:
    """Build the map ``request`` asks for. Raises :class:`GridmapError` (bad input, a log that
    cannot be mapped this way) before any mapping where it can."""
    hooks = hooks or BuildHooks()
    return map_stage(request, pose_stage(request, hooks), hooks)


def map_stage(request: BuildRequest, placed: Placed, hooks: BuildHooks | None = None) -> MapBuild:
    """The map of a log :func:`pose_stage` placed for ``request``."""
    from gridmap_cli.mapping.pipeline import build_map

    hooks = hooks or BuildHooks()
    options = _chosen_options(request, placed)
    started = time.perf_counter()
    result = build_map(placed.log, placed.robot, options, hooks.mapped, hooks.between_passes)
    summary: dict[str, object] = {k: dict(v) for k, v in placed.posed.summary.items()}
    if options.correct_odometry:
        summary["odometry_corrected"] = True
    if placed.posed.motion is not None:
        summary["motion"] = placed.posed.motion
    if result.odometry_check is not None:
        summary["odometry_check"] = result.odometry_check.as_dict()
        summary["odometry_check_note"] = result.odometry_check.summary()
    seconds = {"read": placed.read_s, "map": time.perf_counter() - started}
    return MapBuild(result.map, placed, options, result, summary, placed.warnings, seconds)


def _chosen_options(request: BuildRequest, placed: Placed) -> BuildOptions:
    """The request's options for the track the pose source gave: the graph's belief where it
    has one; for a source that chose by the log, no odometry correction of another track, and
    the error-aware map's need of an odometry error where the choice was the odometry."""
    options = request.options
    if placed.posed.belief is not None and options.mode == "error-aware":
        # the graph's marginals and draws, not the odometry's
        return dataclasses.replace(options, pose_belief=placed.posed.belief)
    if not pose_source(request.pose).chooses:
        return options
    own = "odometry" in pose_source(placed.posed.source).needs
    if options.correct_odometry and not own:
        options = dataclasses.replace(options, correct_odometry=False)
    if options.mode == "error-aware" and not options.odometry_error_given:
        raise UsageError(
            f"{given('mode', 'error-aware')} needs the odometry error: "
            f"{given('odometry_error', 'FILE')} (gridmap calibrate writes one) or "
            f"{given('odometry_coefficients', 'NAME=VALUE')}; {given('pose', request.pose)} "
            f"mapped with the {placed.posed.source} track, which carries no uncertainty of its own"
        )
    return options


def move_track(track: PoseTrack, first: tuple[float, float, float]) -> PoseTrack:
    """``track`` moved rigidly so that its first pose is ``first`` (x_m, y_m, yaw_rad)."""
    if len(track) == 0:
        return track
    import numpy as np

    from gridmap_cli.geometry import compose, inverse

    ix, iy, ith = inverse(track.x_m[:1], track.y_m[:1], track.theta_rad[:1])
    x0, y0, th0 = (np.array([v]) for v in first)
    tx, ty, tth = compose(x0, y0, th0, ix, iy, ith)
    x, y, th = compose(tx, ty, tth, track.x_m, track.y_m, track.theta_rad)
    return PoseTrack(stamp_ns=track.stamp_ns, x_m=x, y_m=y, theta_rad=th)


def robot_of(log: RangeLog, inputs: Sequence[Path] = ()) -> RobotDescription | None:
    """The robot a log names on its ``# robot:`` line (a preset, or a file beside the log),
    or None."""
    from gridmap_cli.robot import robot_from_log

    path = inputs[0] if inputs else Path(log.source)
    return robot_from_log(path, log.metadata)


def _robot(robot: RobotDescription | str | None) -> RobotDescription | None:
    if robot is None or isinstance(robot, RobotDescription):
        return robot
    from gridmap_cli.robot import load_robot

    return load_robot(robot)


def _read(
    request: BuildRequest, held: bool, robot: RobotDescription | None, hooks: BuildHooks
) -> RangeLog:
    """The request's log: the one given, or its inputs read (a long log's readings left in
    its file unless the pose source or a time window needs them held)."""
    if request.log is not None:
        if request.inputs:
            raise GridmapError("give the logs to read or a log already read, not both")
        return request.log
    if not request.inputs:
        raise GridmapError(f"nothing to map: give {given('inputs')} or {given('log')}")
    window = request.selection.start is not None or request.selection.end is not None
    stream = request.stream and not held and not window
    # a source that reads the scans can take the motion from them where the log has no odometry
    options = dataclasses.replace(
        request.read_options,
        robot=robot,
        stream=stream,
        odometry_optional=pose_source(request.pose).uses_laser,
    )
    read = hooks.read or _read_logs
    with hooks.reading() if hooks.reading is not None else contextlib.nullcontext():
        return read(request.inputs, request.log_format, options)


def _read_logs(paths: Sequence[Path], log_format: str | None, options: ReadOptions) -> RangeLog:
    from gridmap_cli.readers import read_logs

    return read_logs(paths, log_format, options)


def _reference_note(request: BuildRequest) -> str | None:
    """A warning for an error-aware map of a reference track with a nonzero odometry error:
    the reference carries no odometry drift, so the spread blurs a map that has none. None
    otherwise."""
    from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise

    model, source = request.options.odometry_error, pose_source(request.pose)
    if "reference" not in source.needs or request.options.mode != "error-aware":
        return None
    if model is None or StepNoise.of(model).is_zero:
        return None
    odometry = next(s.name for s in SOURCES if "odometry" in s.needs)
    return (
        f"{given('pose', source.name)} {given('mode', 'error-aware')}: the odometry's error is "
        "spread over the reference track, which has no odometry drift, so the map is blurred "
        f"for nothing; map the reference with {given('mode', 'standard')}, or the odometry "
        f"({given('pose', odometry)}) error-aware"
    )


def _say(hooks: BuildHooks, note: str) -> None:
    if hooks.warn is not None:
        hooks.warn(note)
