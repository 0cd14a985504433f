"""The map options of ``gridmap build``: what to map and how (robot, log format, resolution,
mapping mode, map mode, thresholds, pose source, ROS topics, part of the log, the error-aware
model), as click decorators.

:func:`map_options` adds them all, in the order ``gridmap build --help`` lists them,
and hands the command one :class:`~gridmap_cli.runs.settings.MapOptions`: ``build`` and
``batch`` take the same set, defined once; :func:`~gridmap_cli.runs.settings.map_settings`
checks them. Each option is also its own decorator, for a command that takes one of them.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import click

from gridmap_cli.cli.common import format_option, selection_options, topic_options
from gridmap_cli.mapping.models.fading import ErrorAwareParams
from gridmap_cli.mapping.models.ray import LASER_NO_ECHO_FREE_M
from gridmap_cli.mapping.models.standard import StandardSonarParams
from gridmap_cli.mapping.options import MAPPING_MODES, BuildOptions
from gridmap_cli.poses.sources import DEFAULT_SOURCE, pose_help, source_names
from gridmap_cli.robot import preset_names
from gridmap_cli.runs.settings import MapOptions
from gridmap_cli.writers.map_image import IMAGE_FORMATS, MAP_MODES

F = TypeVar("F", bound=Callable[..., object])

robot_option = click.option(
    "--robot",
    help=f"Robot preset ({', '.join(preset_names())}), robot YAML file or ARIA .p file; "
    "default: the log's own '# robot:' line.",
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
    type=click.Choice(source_names()),
    default=DEFAULT_SOURCE,
    show_default=True,
    help=pose_help("Map with"),
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


correct_odometry_option = click.option(
    "--correct-odometry/--no-correct-odometry",
    default=None,
    help="Take the odometry's systematic errors (the signed biases of --odometry-error FILE, "
    "version 3) out of its track before mapping; the error-aware spread then has the random "
    "part alone. Default: on in error-aware mode when the file holds biases (a known bias is "
    "corrected, not blurred), off in standard mode; --no-correct-odometry spreads the biases "
    "as errors instead.",
)


#: Every map option, in help order (:func:`map_options` makes them one value).
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
    """Add :data:`MAP_OPTIONS` to a command, listed in that order; the command receives them
    (with ``--error-samples``, which it declares where its help lists it) as one value,
    ``map_options``, a :class:`MapOptions`."""

    @functools.wraps(func)
    def gathered(*args: Any, **kwargs: Any) -> Any:
        ctx = click.get_current_context()

        def chosen(name: str) -> Any:  # None where the default stands: the library's own
            value = kwargs.pop(name)
            default = ctx.get_parameter_source(name) == click.core.ParameterSource.DEFAULT
            return None if default else value

        options = MapOptions(
            robot=kwargs.pop("robot"), log_format=kwargs.pop("log_format"),
            resolution=kwargs.pop("resolution"), mode=kwargs.pop("mode"),
            map_mode=kwargs.pop("map_mode"), occupied=kwargs.pop("occupied"),
            free=kwargs.pop("free"), no_echo_free=kwargs.pop("no_echo_free"),
            max_range=kwargs.pop("max_range"), pose=kwargs.pop("pose"),
            topics=kwargs.pop("topics"), sensors=tuple(kwargs.pop("sensor_patterns")),
            start=kwargs.pop("start"), end=kwargs.pop("end"),
            odometry_error=kwargs.pop("odometry_file"),
            odometry_coefficients=tuple(kwargs.pop("coefficients")),
            trust_length=chosen("trust_length"), max_heading_spread=chosen("max_spread_deg"),
            error_samples=kwargs.pop("error_samples"),
            correct_odometry=kwargs.pop("correct_odometry"),
        )  # fmt: skip
        return func(*args, map_options=options, **kwargs)

    decorated: Callable[..., Any] = gathered
    for option in reversed(MAP_OPTIONS):
        decorated = option(decorated)
    return decorated  # type: ignore[return-value]
