"""Robot descriptions: which range sensors a robot has and where they are mounted, and the
loaders that resolve ``--robot``.

A robot is described in YAML (format documented in ``docs/robot-format.md``, JSON Schema in
``schemas/robot.schema.json``; :mod:`.robot_yaml`) or by an ARIA robot parameter file (``.p``;
:mod:`.aria_params`). The presets ``p3at`` and ``p3dx`` ship as package data, with the sonar ring
exactly as ARIA's ``params/p3at.p`` and ``params/p3dx.p`` give it, converted to SI.

May import: the core (errors, limits, yamlfile). Readers import this package, never the reverse.
"""

from __future__ import annotations

from collections.abc import Mapping
from importlib import resources
from pathlib import Path

from gridmap_cli.errors import InputFileError, RobotDescriptionError, UnknownRobotError, given
from gridmap_cli.limits import read_settings_text
from gridmap_cli.robot.beams import BeamBook as BeamBook
from gridmap_cli.robot.description import SENSOR_KINDS as SENSOR_KINDS
from gridmap_cli.robot.description import RangeSensor as RangeSensor
from gridmap_cli.robot.description import RobotDescription as RobotDescription
from gridmap_cli.robot.description import SensorMount as SensorMount
from gridmap_cli.robot.description import laser_beams as laser_beams
from gridmap_cli.robot.description import parse_mount as parse_mount
from gridmap_cli.robot.robot_yaml import parse_robot_yaml as parse_robot_yaml


def preset_names() -> list[str]:
    """Names of the robot presets shipped with gridmap."""
    folder = resources.files("gridmap_cli") / "presets"
    return sorted(
        p.name.removesuffix(".yaml") for p in folder.iterdir() if p.name.endswith(".yaml")
    )


def load_robot(spec: str, folder: Path | None = None) -> RobotDescription:
    """Resolve ``--robot``: a preset name, a robot YAML file or an ARIA ``.p`` parameter file.

    A relative file name is taken in ``folder`` (the working directory when None).
    """
    if spec in preset_names():
        res = resources.files("gridmap_cli") / "presets" / f"{spec}.yaml"
        return parse_robot_yaml(res.read_text(encoding="utf-8"), f"preset:{spec}")
    path = Path(spec) if folder is None else folder / spec
    if path.is_file():
        if path.suffix.lower() == ".p":
            # imported here: only a .p robot needs the ARIA parser
            from gridmap_cli.robot.aria_params import read_aria_params

            return read_aria_params(path).robot()
        try:
            text = read_settings_text(path, "a robot description")
        except (OSError, UnicodeDecodeError) as exc:
            raise RobotDescriptionError(path, f"cannot read: {exc}") from exc
        return parse_robot_yaml(text, str(path))
    raise UnknownRobotError(spec, preset_names())


def robot_from_log(log: Path, metadata: Mapping[str, str]) -> RobotDescription | None:
    """The robot a log names on its ``# robot:`` line: a preset, or a file beside the log.

    None when the log names no robot. Raises :class:`InputFileError` naming the log when the
    name is neither, and what :func:`load_robot` raises for a malformed description.
    """
    name = metadata.get("robot")
    if not name:
        return None
    try:
        return load_robot(name, folder=log.parent)
    except UnknownRobotError as exc:
        raise InputFileError(
            log,
            f"'# robot: {name}' is neither a preset ({', '.join(preset_names())}) nor a file "
            f"beside the log; give {given('robot')}",
        ) from exc
