"""The map options of ``gridmap build``: what to map and how (robot, log format, resolution,
mapping mode, map mode, thresholds, pose source, ROS topics, part of the log, the error-aware
model), as click decorators, with the usage checks that belong to them.

:func:`map_options` adds them all, in the order ``gridmap build --help`` lists them; each
option is also its own decorator, so another command (``batch``, issue 22) can take the same
set, defined once, instead of its own copies.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import click

from gridmap_cli.cli.common import check_input, selection_options, topic_options
from gridmap_cli.errors import UsageError
from gridmap_cli.mapping.models.fading import ErrorAwareParams
from gridmap_cli.mapping.models.ray import LASER_NO_ECHO_FREE_M, RayParams
from gridmap_cli.mapping.models.standard import StandardSonarParams
from gridmap_cli.mapping.pipeline import MAPPING_MODES, MAX_RESOLUTION_M, BuildOptions
from gridmap_cli.poses.odometry_error import OdometryError, load_odometry_error
from gridmap_cli.poses.sync import POSE_SOURCES
from gridmap_cli.readers import format_names
from gridmap_cli.robot import preset_names
from gridmap_cli.writers.map_image import IMAGE_FORMATS, MAP_MODES

F = TypeVar("F", bound=Callable[..., object])

robot_option = click.option(
    "--robot",
    help=f"Robot preset ({', '.join(preset_names())}), robot YAML file or ARIA .p file; "
    "default: the log's own '# robot:' line.",
)
format_option = click.option(
    "--format", "log_format", type=click.Choice(format_names()), help="Log format."
)


def image_format_option(help_text: str) -> Callable[[F], F]:
    """``--fmt``, the map image's format (map_saver_cli's flag); each command says what it
    does there (build: the format of ``-f``; batch: of every map)."""
    return click.option("--fmt", "image_format", type=click.Choice(IMAGE_FORMATS), help=help_text)


resolution_option = click.option(
    "--resolution", type=float, default=0.05, show_default=True, help="Cell size in metres."
)


class MappingModeChoice(click.Choice):  # type: ignore[type-arg]
    """--mode's choices; a map mode (map_saver's ``--mode trinary``) is pointed to --map-mode."""

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, str) and value.lower() in MAP_MODES:
            self.fail(
                f"{value!r} is a map mode (how the image stores occupancy): give --map-mode "
                f"{value.lower()}; --mode is the mapping algorithm, one of "
                f"{', '.join(repr(m) for m in MAPPING_MODES)}",
                param,
                ctx,
            )
        return super().convert(value, param, ctx)


mode_option = click.option(
    "--mode",
    type=MappingModeChoice(MAPPING_MODES),
    default="standard",
    show_default=True,
    help="Mapping algorithm.",
)
map_mode_option = click.option(
    "--map-mode",
    type=click.Choice(MAP_MODES),
    default="trinary",
    show_default=True,
    help="How occupancy is stored in the image (map_server modes).",
)
occupied_option = click.option(
    "--occupied",
    "--occ",
    "occupied",
    type=float,
    default=0.65,
    show_default=True,
    help="Probability at or above which a cell is occupied.",
)
free_option = click.option(
    "--free",
    type=float,
    default=0.25,
    show_default=True,
    help="Probability at or below which a cell is free.",
)
no_echo_free_option = click.option(
    "--no-echo-free",
    type=float,
    default=None,
    metavar="METRES",
    help="Metres of free space a max-range (no echo) reading clears, at most the sensor's "
    f"range; 0 ignores them [default: sonars {StandardSonarParams.no_echo_free_m:g}, lasers "
    f"{LASER_NO_ECHO_FREE_M:g}].",
)
max_range_option = click.option(
    "--max-range",
    type=float,
    default=None,
    metavar="METRES",
    help="Lasers: cut longer readings to free space up to METRES (no wall at their end); "
    "they never set the map's bounds [default: the laser's own range].",
)
pose_option = click.option(
    "--pose",
    type=click.Choice((*POSE_SOURCES, "slam")),
    default="odometry",
    show_default=True,
    help="Map with the odometry, with the log's global pose (ARIA robotGlobal, CSV true_*, "
    "CARMEN's corrected poses or TRUEPOS), with the odometry corrected by matching the laser "
    "scans (scan-matched), or with that and loop closures on a pose graph (slam).",
)

#: The error-aware model's options; :func:`error_aware_settings` checks them.
ERROR_AWARE_OPTIONS = (
    click.option(
        "--odometry-error",
        "odometry_file",
        type=click.Path(path_type=Path, readable=False),
        help="Error-aware mode: odometry-error YAML (what gridmap calibrate writes).",
    ),
    click.option(
        "--odometry-coefficient",
        "coefficients",
        multiple=True,
        metavar="NAME=VALUE",
        help="Error-aware mode: set one f/g coefficient (docs/odometry-error.md names them), e.g. "
        "range_m_per_m=0.01; overrides the file; repeatable.",
    ),
    click.option(
        "--trust-length",
        type=float,
        default=ErrorAwareParams.trust_length_m,
        show_default=True,
        help="Error-aware mode, --error-samples 0: the smallest pose spread (m) a cell can tell "
        "apart.",
    ),
    click.option(
        "--max-heading-spread",
        "max_spread_deg",
        type=float,
        default=math.degrees(ErrorAwareParams.max_heading_spread_rad),
        show_default=True,
        help="Error-aware mode: degrees of the propagated heading standard deviation beyond "
        "which readings are left out (their cells stay unknown); inf, the default, keeps every "
        "reading.",
    ),
)

error_samples_option = click.option(
    "--error-samples",
    type=click.IntRange(min=0),
    default=None,
    metavar="K",
    help=f"Error-aware mode: average the standard maps of K tracks sampled from the odometry "
    f"error (the expected map; default {BuildOptions.error_samples}); 0 fades each reading's "
    f"evidence by its pose spread instead (faster, less true: docs/sensor-model.md).",
)


def error_samples_setting(mode: str, error_samples: int | None) -> int:
    """--error-samples, checked: it belongs to --mode error-aware."""
    if error_samples is not None and mode != "error-aware":
        raise UsageError("--error-samples applies to --mode error-aware")
    return BuildOptions.error_samples if error_samples is None else error_samples


correct_odometry_option = click.option(
    "--correct-odometry/--no-correct-odometry",
    default=None,
    help="Take the odometry's systematic errors (the signed biases of --odometry-error FILE, "
    "version 3) out of its track before mapping; the error-aware spread then has the random "
    "part alone. Default: on in error-aware mode when the file holds biases (a known bias is "
    "corrected, not blurred), off in standard mode; --no-correct-odometry spreads the biases "
    "as errors instead.",
)


#: Every map option, in help order: the command receives robot, log_format, resolution, mode,
#: map_mode, occupied, free, no_echo_free, max_range, pose, topics (a ReadOptions), sensor_patterns,
#: start, end, odometry_file, coefficients, trust_length, max_spread_deg and correct_odometry.
MAP_OPTIONS: tuple[Callable[[Callable[..., Any]], Callable[..., Any]], ...] = (
    robot_option,
    format_option,
    resolution_option,
    mode_option,
    map_mode_option,
    occupied_option,
    free_option,
    no_echo_free_option,
    max_range_option,
    pose_option,
    topic_options,
    selection_options(),
    *ERROR_AWARE_OPTIONS,
    correct_odometry_option,
)


def map_options(func: F) -> F:
    """Add :data:`MAP_OPTIONS` to a command, listed in that order."""
    decorated: Callable[..., Any] = func
    for option in reversed(MAP_OPTIONS):
        decorated = option(decorated)
    return decorated  # type: ignore[return-value]


def check_thresholds(occupied: float, free: float) -> None:
    """--occupied and --free: probabilities with free below occupied."""
    if not (0.0 <= free < occupied <= 1.0):
        raise UsageError(f"need 0 <= --free < --occupied <= 1, got {free} and {occupied}")


def check_resolution(resolution: float) -> None:
    """--resolution: a positive cell size no larger than :data:`MAX_RESOLUTION_M`."""
    if not (resolution > 0.0 and math.isfinite(resolution)):
        raise UsageError(f"--resolution must be a positive number of metres, got {resolution}")
    if resolution > MAX_RESOLUTION_M:
        raise UsageError(
            f"--resolution {resolution:g} m: cells larger than {MAX_RESOLUTION_M:g} m hold whole "
            "rooms, and the map would be a few cells of nothing (cell size is in metres: 0.05 "
            "is 5 cm)"
        )


def sonar_params(no_echo_free: float | None) -> StandardSonarParams:
    """The standard model's settings from --no-echo-free (None: the model's default)."""
    try:
        return StandardSonarParams(
            no_echo_free_m=StandardSonarParams.no_echo_free_m if no_echo_free is None
            else no_echo_free
        )  # fmt: skip
    except ValueError as exc:
        raise UsageError(f"--no-echo-free: {exc}") from exc


def ray_params(no_echo_free: float | None, max_range: float | None) -> RayParams:
    """The ray (laser) model's settings from --no-echo-free and --max-range (None: defaults)."""
    if max_range is not None and not (max_range > 0.0 and math.isfinite(max_range)):
        raise UsageError(f"--max-range must be a positive number of metres, got {max_range}")
    try:
        return RayParams(
            no_echo_free_m=LASER_NO_ECHO_FREE_M if no_echo_free is None else no_echo_free,
            max_range_m=math.inf if max_range is None else max_range,
        )
    except ValueError as exc:
        raise UsageError(f"--no-echo-free: {exc}") from exc


def error_aware_settings(
    mode: str,
    odometry_file: Path | None,
    coefficients: tuple[str, ...],
    trust_length: float,
    max_spread_deg: float = math.degrees(ErrorAwareParams.max_heading_spread_rad),
    graph_uncertainty: bool = False,
    correct_odometry: bool = False,
) -> tuple[ErrorAwareParams, OdometryError | None]:
    """The error-aware model's settings from :data:`ERROR_AWARE_OPTIONS` (usage errors before
    any reading). ``graph_uncertainty``: the pose uncertainty comes from a pose graph
    (``--pose slam``), so the odometry error is optional (only its sonar range error is used).
    ``correct_odometry`` (build's --correct-odometry): the odometry error is read in standard
    mode too, and must hold the signs of its systematic errors."""
    ctx = click.get_current_context()
    trust_given = any(
        ctx.get_parameter_source(name) != click.core.ParameterSource.DEFAULT
        for name in ("trust_length", "max_spread_deg")
    )
    given = odometry_file is not None or bool(coefficients)
    if correct_odometry:
        if odometry_file is None:
            raise UsageError(
                "--correct-odometry needs the odometry's biases: --odometry-error FILE "
                "(gridmap calibrate writes one)"
            )
        if mode != "error-aware" and (coefficients or trust_given):
            raise UsageError(
                "--odometry-coefficient, --trust-length and --max-heading-spread apply to "
                "--mode error-aware"
            )
    elif mode != "error-aware":
        if given or trust_given:
            raise UsageError(
                "--odometry-error, --odometry-coefficient, --trust-length and "
                "--max-heading-spread apply to --mode error-aware"
            )
        return ErrorAwareParams(), None
    if mode == "error-aware" and not given and not graph_uncertainty:
        raise UsageError(
            "--mode error-aware needs the odometry error: --odometry-error FILE (gridmap "
            "calibrate writes one) or --odometry-coefficient NAME=VALUE"
        )
    try:
        params = ErrorAwareParams(trust_length_m=trust_length)
    except ValueError as exc:
        raise UsageError(f"--trust-length: {exc}") from exc
    if not max_spread_deg > 0:
        raise UsageError(f"--max-heading-spread must be a positive angle, got {max_spread_deg}")
    params = dataclasses.replace(params, max_heading_spread_rad=math.radians(max_spread_deg))
    names = [f.name for f in dataclasses.fields(OdometryError)]
    overrides: dict[str, float] = {}
    for item in coefficients:
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or name not in names:
            raise UsageError(
                f"--odometry-coefficient {item!r}: expected NAME=VALUE, NAME one of "
                f"{', '.join(names)}"
            )
        try:
            overrides[name] = float(text)
        except ValueError:
            raise UsageError(f"--odometry-coefficient {item!r}: {text!r} is not a number") from None
    if odometry_file is not None:
        check_input(odometry_file, folder_ok=False)
    model = load_odometry_error(odometry_file) if odometry_file is not None else OdometryError()
    try:
        model = dataclasses.replace(model, **overrides)
    except ValueError as exc:
        raise UsageError(f"--odometry-coefficient: {exc}") from exc
    unsigned = (model.range_m_per_m, model.bearing_rad_per_rad, model.heading_drift_rad_per_m)
    if correct_odometry and not model.has_bias and any(unsigned):
        raise UsageError(
            f"--correct-odometry: {odometry_file} holds systematic errors without their signs "
            "(a file older than version 3): run gridmap calibrate again"
        )
    return params, model


def build_settings(
    resolution: float,
    mode: str,
    occupied: float,
    free: float,
    no_echo_free: float | None,
    max_range: float | None,
    pose: str,
    odometry_file: Path | None,
    coefficients: tuple[str, ...],
    trust_length: float,
    max_spread_deg: float,
    error_samples: int | None,
    correct_odometry: bool | None,
    fused: bool = False,
) -> BuildOptions:
    """The map options as the mapping pipeline takes them, every usage check made (build and
    batch alike, before any reading). ``correct_odometry`` None (neither --correct-odometry nor
    --no-correct-odometry) corrects the biases of the odometry error when the map is
    error-aware, of the robot's own odometry (``pose`` odometry, not ``fused``), and the file
    holds signed biases: :func:`auto_correction`."""
    check_thresholds(occupied, free)
    check_resolution(resolution)
    error_aware, odometry_error = error_aware_settings(
        mode, odometry_file, coefficients, trust_length, max_spread_deg, pose == "slam",
        correct_odometry=bool(correct_odometry),
    )  # fmt: skip
    if correct_odometry and (pose != "odometry" or fused):
        raise UsageError(
            "--correct-odometry corrects the robot's own odometry: it takes --pose odometry "
            "and one log, no --fuse"
        )
    if correct_odometry is None:
        correct_odometry = auto_correction(mode, pose, fused, odometry_error)
    return BuildOptions(
        resolution_m=resolution,
        mode=mode,
        sonar=sonar_params(no_echo_free),
        ray=ray_params(no_echo_free, max_range),
        error_aware=error_aware,
        odometry_error=odometry_error,
        error_samples=error_samples_setting(mode, error_samples),
        correct_odometry=correct_odometry,
    )


def auto_correction(mode: str, pose: str, fused: bool, model: OdometryError | None) -> bool:
    """Whether a build given neither --correct-odometry nor --no-correct-odometry corrects the
    odometry's biases: in error-aware mode, of the robot's own odometry of one log, with an
    odometry error that knows the biases' signs (version 3). Spreading a known bias as a
    random error blurs what the track can simply be rid of (issue 19: on the Intel lab the
    uncorrected error-aware map scored 1.17x the corrected standard map, the corrected one
    0.81x)."""
    if mode != "error-aware" or pose != "odometry" or fused or model is None:
        return False
    return model.has_bias
