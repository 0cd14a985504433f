"""The map options as one value, :class:`MapOptions`, and the checks that turn them into the
:class:`~gridmap_cli.mapping.options.BuildOptions` every mapping stage takes.

``gridmap build`` and ``batch`` make one :class:`MapOptions` from their command line; a Python
caller makes one by hand. :func:`map_settings` checks them all before any log is read (the
errors name what was given as the caller gave it: :func:`gridmap_cli.errors.given`), and
:meth:`MapOptions.request` makes the :class:`~gridmap_cli.runs.build.BuildRequest` of a log.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

from gridmap_cli.errors import InputFileError, UsageError, given
from gridmap_cli.mapping.models.fading import ErrorAwareParams
from gridmap_cli.mapping.models.ray import LASER_NO_ECHO_FREE_M, RayParams
from gridmap_cli.mapping.models.standard import StandardSonarParams
from gridmap_cli.mapping.options import MAPPING_MODES, MAX_RESOLUTION_M, BuildOptions
from gridmap_cli.mapping.selection import Selection
from gridmap_cli.poses.odometry_error import OdometryError, load_odometry_error
from gridmap_cli.poses.sources import DEFAULT_SOURCE, ODOMETRY_SOURCE, SOURCES, pose_source
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RobotDescription
from gridmap_cli.runs.build import BuildRequest

#: ``-`` as a file name: standard input for a log, standard output for what is written.
STDIO = Path("-")


@dataclass(frozen=True)
class MapOptions:
    """What to map and how, as a caller gives it (every field optional).

    ``robot``: a preset name or a robot file (None: the log's own ``# robot:`` line);
    ``log_format``: the reader to use (None: sniffed); ``resolution``: cell size in metres;
    ``mode``: "standard" or "error-aware"; ``map_mode``, ``occupied``, ``free``: how the image
    stores occupancy; ``no_echo_free``, ``max_range``: metres (None: the models' defaults);
    ``pose``: a pose source's name; ``topics``: ROS topic and frame choices; ``sensors``,
    ``start``, ``end``: the part of the log to map (:class:`Selection`); the error-aware
    model: ``odometry_error`` (a file gridmap calibrate writes), ``odometry_coefficients``
    (``NAME=VALUE`` overrides), ``trust_length`` (m) and ``max_heading_spread`` (degrees;
    None: the defaults), ``error_samples`` (None: the default); ``correct_odometry`` (None:
    on when the map is error-aware and the file knows the biases' signs).
    """

    robot: str | None = None
    log_format: str | None = None
    resolution: float = 0.05
    mode: str = "standard"
    map_mode: str = "trinary"
    occupied: float = 0.65
    free: float = 0.25
    no_echo_free: float | None = None
    max_range: float | None = None
    pose: str = DEFAULT_SOURCE
    topics: ReadOptions = field(default_factory=ReadOptions)
    sensors: tuple[str, ...] = ()
    start: str | None = None
    end: str | None = None
    odometry_error: Path | None = None
    odometry_coefficients: tuple[str, ...] = ()
    trust_length: float | None = None
    max_heading_spread: float | None = None
    error_samples: int | None = None
    correct_odometry: bool | None = None

    def selection(self) -> Selection:
        """The part of the log to map; :class:`UsageError` for a bad pattern or time."""
        return Selection.parse(self.sensors, self.start, self.end)

    def request(
        self,
        inputs: tuple[Path, ...] | list[Path] | Path | str = (),
        log: RangeLog | None = None,
        robot: RobotDescription | None = None,
        jobs: int = 1,
    ) -> BuildRequest:
        """The build of ``inputs`` (paths of logs read as one) or ``log`` (already read) with
        these options, every check made; ``robot`` a description already loaded, instead of
        :attr:`robot`."""
        paths = (inputs,) if isinstance(inputs, (str, Path)) else tuple(inputs)
        settings = dataclasses.replace(map_settings(self), jobs=jobs)
        return BuildRequest(
            inputs=tuple(Path(p) for p in paths), log=log,
            robot=robot if robot is not None else self.robot, options=settings,
            pose=self.pose, selection=self.selection(), log_format=self.log_format,
            read_options=self.topics,
        )  # fmt: skip


def map_settings(options: MapOptions, fused: bool = False) -> BuildOptions:
    """The map options as the mapping pipeline takes them, every check made (before any
    reading). ``correct_odometry`` None corrects the biases of the odometry error when the
    map is error-aware, of the robot's own odometry of one log (not ``fused``), and the file
    holds signed biases: :func:`auto_correction`."""
    check_thresholds(options.occupied, options.free)
    check_resolution(options.resolution)
    pose_source(options.pose)
    if options.mode not in MAPPING_MODES:
        raise UsageError(f"unknown mapping mode '{options.mode}' (known: {MAPPING_MODES})")
    error_aware, odometry_error = error_aware_settings(options)
    correct = options.correct_odometry
    # a source that chooses by the log maps the odometry when given its error model
    chooses = pose_source(options.pose).chooses
    own = chooses or _own_odometry(options.pose)
    if correct and (not own or fused):
        odometry = next(s.name for s in SOURCES if _own_odometry(s.name))
        raise UsageError(
            f"{given('correct_odometry')} corrects the robot's own odometry: it takes "
            f"{given('pose', odometry)} and one log, no {given('fuse')}"
        )
    if correct is None:
        pose = ODOMETRY_SOURCE if chooses else options.pose
        correct = auto_correction(options.mode, pose, fused, odometry_error)
    return BuildOptions(
        resolution_m=options.resolution,
        mode=options.mode,
        sonar=sonar_params(options.no_echo_free),
        ray=ray_params(options.no_echo_free, options.max_range),
        error_aware=error_aware,
        odometry_error=odometry_error,
        error_samples=error_samples_setting(options.mode, options.error_samples),
        correct_odometry=correct,
        odometry_error_given=options.odometry_error is not None
        or bool(options.odometry_coefficients),
        # an error-aware map of the robot's own odometry checks the file against the log's laser
        check_odometry_error=options.mode == "error-aware"
        and own
        and not fused
        and options.odometry_error is not None,
    )


def error_samples_setting(mode: str, error_samples: int | None) -> int:
    """The samples of the expected map, checked: they belong to the error-aware mode."""
    if error_samples is not None and mode != "error-aware":
        raise UsageError(f"{given('error_samples')} applies to {given('mode', 'error-aware')}")
    return BuildOptions.error_samples if error_samples is None else error_samples


def check_thresholds(occupied: float, free: float) -> None:
    """The thresholds: probabilities with free below occupied."""
    if not (0.0 <= free < occupied <= 1.0):
        raise UsageError(
            f"need 0 <= {given('free')} < {given('occupied')} <= 1, got {free} and {occupied}"
        )


def check_resolution(resolution: float) -> None:
    """The cell size: positive and no larger than :data:`MAX_RESOLUTION_M`."""
    if not (resolution > 0.0 and math.isfinite(resolution)):
        raise UsageError(
            f"{given('resolution')} must be a positive number of metres, got {resolution}"
        )
    if resolution > MAX_RESOLUTION_M:
        raise UsageError(
            f"{given('resolution', f'{resolution:g}')} m: cells larger than "
            f"{MAX_RESOLUTION_M:g} m hold whole rooms, and the map would be a few cells of "
            "nothing (cell size is in metres: 0.05 is 5 cm)"
        )


def sonar_params(no_echo_free: float | None) -> StandardSonarParams:
    """The standard model's settings from the no-echo free length (None: the default)."""
    try:
        return StandardSonarParams(
            no_echo_free_m=StandardSonarParams.no_echo_free_m if no_echo_free is None
            else no_echo_free
        )  # fmt: skip
    except ValueError as exc:
        raise UsageError(f"{given('no_echo_free')}: {exc}") from exc


def ray_params(no_echo_free: float | None, max_range: float | None) -> RayParams:
    """The ray (laser) model's settings (None: the defaults)."""
    if max_range is not None and not (max_range > 0.0 and math.isfinite(max_range)):
        raise UsageError(
            f"{given('max_range')} must be a positive number of metres, got {max_range}"
        )
    try:
        return RayParams(
            no_echo_free_m=LASER_NO_ECHO_FREE_M if no_echo_free is None else no_echo_free,
            max_range_m=math.inf if max_range is None else max_range,
        )
    except ValueError as exc:
        raise UsageError(f"{given('no_echo_free')}: {exc}") from exc


def error_aware_settings(options: MapOptions) -> tuple[ErrorAwareParams, OdometryError | None]:
    """The error-aware model's settings (usage errors before any reading). With the pose
    graph's uncertainty (a source that knows it) the odometry error is optional (only its
    sonar range error is used); correcting the odometry reads the file in standard mode too,
    and it must hold the signs of its systematic errors."""
    mode, odometry_file = options.mode, options.odometry_error
    coefficients, correct = options.odometry_coefficients, bool(options.correct_odometry)
    trust_given = options.trust_length is not None or options.max_heading_spread is not None
    given_model = odometry_file is not None or bool(coefficients)
    model_flags = (
        f"{given('odometry_coefficients')}, {given('trust_length')} and "
        f"{given('max_heading_spread')} apply to {given('mode', 'error-aware')}"
    )
    if correct:
        if odometry_file is None:
            raise UsageError(
                f"{given('correct_odometry')} needs the odometry's biases: "
                f"{given('odometry_error', 'FILE')} (gridmap calibrate writes one)"
            )
        if mode != "error-aware" and (coefficients or trust_given):
            raise UsageError(model_flags)
    elif mode != "error-aware":
        if given_model or trust_given:
            raise UsageError(f"{given('odometry_error')}, {model_flags}")
        return ErrorAwareParams(), None
    if mode == "error-aware" and not given_model and not pose_source(options.pose).belief:
        raise UsageError(
            f"{given('mode', 'error-aware')} needs the odometry error: "
            f"{given('odometry_error', 'FILE')} (gridmap calibrate writes one) or "
            f"{given('odometry_coefficients', 'NAME=VALUE')}"
        )
    trust = options.trust_length
    if trust is None:
        trust = ErrorAwareParams.trust_length_m
    try:
        params = ErrorAwareParams(trust_length_m=trust)
    except ValueError as exc:
        raise UsageError(f"{given('trust_length')}: {exc}") from exc
    spread = options.max_heading_spread
    if spread is not None:
        if not spread > 0:
            raise UsageError(
                f"{given('max_heading_spread')} must be a positive angle, got {spread}"
            )
        params = dataclasses.replace(params, max_heading_spread_rad=math.radians(spread))
    model = _odometry_error(odometry_file, coefficients)
    unsigned = (model.range_m_per_m, model.bearing_rad_per_rad, model.heading_drift_rad_per_m)
    if correct and not model.has_bias and any(unsigned):
        raise UsageError(
            f"{given('correct_odometry')}: {odometry_file} holds systematic errors without "
            "their signs (a file older than version 3): run gridmap calibrate again"
        )
    return params, model


def _odometry_error(odometry_file: Path | None, coefficients: tuple[str, ...]) -> OdometryError:
    """The odometry error of ``odometry_file`` (or the zero model) with ``coefficients``
    (``NAME=VALUE``) set."""
    names = [f.name for f in dataclasses.fields(OdometryError)]
    overrides: dict[str, float] = {}
    for item in coefficients:
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or name not in names:
            raise UsageError(
                f"{given('odometry_coefficients', repr(item))}: expected NAME=VALUE, NAME one of "
                f"{', '.join(names)}"
            )
        try:
            overrides[name] = float(text)
        except ValueError:
            raise UsageError(
                f"{given('odometry_coefficients', repr(item))}: {text!r} is not a number"
            ) from None
    if odometry_file is not None:
        check_input(odometry_file, folder_ok=False)
    model = load_odometry_error(odometry_file) if odometry_file is not None else OdometryError()
    try:
        return dataclasses.replace(model, **overrides)
    except ValueError as exc:
        raise UsageError(f"{given('odometry_coefficients')}: {exc}") from exc


def auto_correction(mode: str, pose: str, fused: bool, model: OdometryError | None) -> bool:
    """Whether a build not told either way corrects the odometry's biases: in error-aware
    mode, of the robot's own odometry of one log, with an odometry error that knows the
    biases' signs (version 3). Spreading a known bias as a random error blurs what the track
    can simply be rid of (docs/odometry-error.md)."""
    if mode != "error-aware" or not _own_odometry(pose) or fused or model is None:
        return False
    return model.has_bias


def _own_odometry(pose: str) -> bool:
    """True for a pose source that maps with the robot's own odometry, as logged."""
    return "odometry" in pose_source(pose).needs


def check_input(log: Path, folder_ok: bool = True) -> None:
    """A file the caller named must exist and be readable: a file, or a folder (rosbag2) when
    ``folder_ok``; ``-`` is standard input. What cannot be read is bad data, as a missing file
    is, never a usage error."""
    if log == STDIO:
        return
    if not log.exists():
        if log.is_symlink():
            raise InputFileError(
                log, f"a symbolic link to {os.readlink(log)}, which does not exist"
            )
        raise InputFileError(log, "no such file")
    if log.is_dir():
        if not folder_ok:
            raise InputFileError(log, "a directory, where a file is expected")
        if not os.access(log, os.R_OK | os.X_OK):
            raise InputFileError(log, "cannot read the folder: permission denied")
        return
    if not log.is_file():
        raise InputFileError(log, "not a regular file or folder")
    try:
        with open(log, "rb"):
            pass
    except OSError as exc:
        raise InputFileError(log, f"cannot read: {exc.strerror or exc}") from exc
