"""Robot descriptions in YAML (``docs/robot-format.md``, ``schemas/robot.schema.json``), with
errors that name the file and line."""

from __future__ import annotations

import math
from typing import Any

import yaml

from gridmap_cli.errors import RobotDescriptionError
from gridmap_cli.limits import MAX_LASER_SAMPLES
from gridmap_cli.robot.description import (
    SENSOR_KINDS,
    RangeSensor,
    RobotDescription,
    SensorMount,
    laser_beams,
)
from gridmap_cli.yamlfile import yaml_problem

_SENSOR_KEYS = {
    "name",
    "kind",
    "x_m",
    "y_m",
    "yaw_deg",
    "beam_width_deg",
    "min_range_m",
    "max_range_m",
    "first_deg",
    "last_deg",
    "samples",
    "upside_down",
}
_LASER_ONLY = ("first_deg", "last_deg", "samples")
#: What a laser entry that gives only its mounting leaves to the recording's scans (an entry
#: with one of them describes its beams, and needs the rest).
_FROM_SCANS = ("first_deg", "last_deg", "samples", "min_range_m", "max_range_m")


def _number(source: str, where: str, value: Any, line: int | None) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise RobotDescriptionError(source, f"{where} must be a number, got {value!r}", line)
    out = float(value)
    if not math.isfinite(out):
        raise RobotDescriptionError(source, f"{where} must be finite, got {value!r}", line)
    return out


def parse_robot_yaml(text: str, source: str) -> RobotDescription:
    """Parse a robot description from YAML text; ``source`` names it in error messages."""
    try:
        # compose first so that errors can point at the line of the offending sensor
        node = yaml.compose(text)
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        line, problem = yaml_problem(exc)
        raise RobotDescriptionError(source, problem, line) from exc
    if not isinstance(doc, dict):
        raise RobotDescriptionError(source, "expected a mapping with 'name' and 'sensors'")
    if doc.get("gridmap-robot") != 1:
        raise RobotDescriptionError(source, "missing 'gridmap-robot: 1' (format version)")
    # a file holding one laser's mounting needs no name: its own serves
    name = doc.get("name", source.rpartition("/")[2].rpartition(".")[0] or source)
    if not isinstance(name, str) or not name:
        raise RobotDescriptionError(source, "'name' must be a non-empty string")
    defaults = doc.get("defaults") or {}
    if not isinstance(defaults, dict):
        raise RobotDescriptionError(source, "'defaults' must be a mapping")
    raw = doc.get("sensors")
    if not isinstance(raw, list) or not raw:
        raise RobotDescriptionError(source, "'sensors' must be a non-empty list")
    lines = _sensor_lines(node)
    sensors: list[RangeSensor] = []
    mounts: list[SensorMount] = []
    for i, entry in enumerate(raw):
        line = lines[i] if i < len(lines) else None
        if not isinstance(entry, dict):
            raise RobotDescriptionError(source, f"sensor {i} must be a mapping", line)
        merged = {**defaults, **entry}
        unknown = sorted(set(merged) - _SENSOR_KEYS)
        if unknown:
            raise RobotDescriptionError(source, f"sensor {i}: unknown keys {unknown}", line)
        kind = merged.get("kind", "sonar")
        if kind not in SENSOR_KINDS:
            raise RobotDescriptionError(
                source, f"sensor {i}: kind must be one of {SENSOR_KINDS}, got {kind!r}", line
            )
        if (
            kind == "laser"
            and not any(k in merged for k in _LASER_ONLY)
            and not any(k in entry for k in ("beam_width_deg", *_FROM_SCANS))
        ):
            mounts.append(_mount(source, line, i, merged, entry))
            continue
        required = {"name", "x_m", "y_m", "yaw_deg", "max_range_m"}
        required |= set(_LASER_ONLY) if kind == "laser" else {"beam_width_deg"}
        missing = sorted(required - set(merged))
        if missing:
            raise RobotDescriptionError(source, f"sensor {i}: missing keys {missing}", line)
        sname = merged["name"]
        if not isinstance(sname, str) or not sname:
            raise RobotDescriptionError(source, f"sensor {i}: 'name' must be a string", line)
        rmin = _number(
            source, f"sensor '{sname}' min_range_m", merged.get("min_range_m", 0.0), line
        )
        rmax = _number(source, f"sensor '{sname}' max_range_m", merged["max_range_m"], line)
        if not 0.0 <= rmin < rmax:
            raise RobotDescriptionError(
                source, f"sensor '{sname}': need 0 <= min_range_m < max_range_m", line
            )
        x = _number(source, f"sensor '{sname}' x_m", merged["x_m"], line)
        y = _number(source, f"sensor '{sname}' y_m", merged["y_m"], line)
        yaw = math.radians(_number(source, f"sensor '{sname}' yaw_deg", merged["yaw_deg"], line))
        if kind == "laser":
            sensors.extend(_laser_beams(source, line, sname, merged, x, y, yaw, rmin, rmax))
            continue
        stray = [k for k in (*_LASER_ONLY, "upside_down") if k in entry]
        if stray:
            raise RobotDescriptionError(
                source, f"sensor '{sname}': {stray} only apply to kind: laser", line
            )
        width = _number(source, f"sensor '{sname}' beam_width_deg", merged["beam_width_deg"], line)
        if not 0.0 <= width < 180.0:
            raise RobotDescriptionError(
                source, f"sensor '{sname}': beam_width_deg must be in [0, 180)", line
            )
        sensors.append(RangeSensor(sname, x, y, yaw, math.radians(width), rmin, rmax, kind))
    names = [s.name for s in sensors] + [m.name for m in mounts]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        # the line of the entry that repeats a name, when the entries themselves repeat it
        seen: set[object] = set()
        where = None
        for i, entry in enumerate(raw):
            name = entry.get("name") if isinstance(entry, dict) else None
            if name in seen and where is None:
                where = lines[i] if i < len(lines) else None
            seen.add(name)
        raise RobotDescriptionError(source, f"duplicate sensor names {dup}", where)
    return RobotDescription(name=name, sensors=tuple(sensors), mounts=tuple(mounts))


def _mount(
    source: str, line: int | None, i: int, merged: dict[str, Any], entry: dict[str, Any]
) -> SensorMount:
    """A laser entry without beams: its mounting alone, the beams from a recording's scans."""
    missing = sorted({"name", "x_m", "y_m", "yaw_deg"} - set(merged))
    if missing:
        raise RobotDescriptionError(source, f"sensor {i}: missing keys {missing}", line)
    sname = merged["name"]
    if not isinstance(sname, str) or not sname:
        raise RobotDescriptionError(source, f"sensor {i}: 'name' must be a string", line)
    x = _number(source, f"sensor '{sname}' x_m", merged["x_m"], line)
    y = _number(source, f"sensor '{sname}' y_m", merged["y_m"], line)
    yaw = math.radians(_number(source, f"sensor '{sname}' yaw_deg", merged["yaw_deg"], line))
    return SensorMount(sname, x, y, yaw, _upside_down(source, line, sname, merged))


def _upside_down(source: str, line: int | None, name: str, entry: dict[str, Any]) -> bool:
    """A laser entry's ``upside_down`` (default false): true or false, nothing else."""
    value = entry.get("upside_down", False)
    if not isinstance(value, bool):
        raise RobotDescriptionError(
            source, f"sensor '{name}': upside_down must be true or false, got {value!r}", line
        )
    return value


def _sensor_lines(node: yaml.Node | None) -> list[int]:
    """1-based line numbers of the entries of the top-level 'sensors' list, for error messages."""
    if not isinstance(node, yaml.MappingNode):
        return []
    for key, value in node.value:
        if getattr(key, "value", None) == "sensors" and isinstance(value, yaml.SequenceNode):
            return [item.start_mark.line + 1 for item in value.value]
    return []


def _laser_beams(
    source: str,
    line: int | None,
    name: str,
    entry: dict[str, Any],
    x: float,
    y: float,
    yaw: float,
    rmin: float,
    rmax: float,
) -> list[RangeSensor]:
    """A scanning laser as one ray sensor per beam: ``<name>_0`` .. ``<name>_<samples-1>``.

    Beam i points ``first_deg + i * (last_deg - first_deg) / (samples - 1)`` from the laser's
    own axis, as ARIA's ``sick<N>conf:`` lines describe a scan.
    """
    first = _number(source, f"sensor '{name}' first_deg", entry["first_deg"], line)
    last = _number(source, f"sensor '{name}' last_deg", entry["last_deg"], line)
    samples = entry["samples"]
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise RobotDescriptionError(
            source, f"sensor '{name}': samples must be a whole number >= 1, got {samples!r}", line
        )
    if samples > MAX_LASER_SAMPLES:
        raise RobotDescriptionError(
            source,
            f"sensor '{name}': {samples:,} samples, above gridmap's limit of "
            f"{MAX_LASER_SAMPLES:,} beams per laser (MAX_LASER_SAMPLES)",
            line,
        )
    if _upside_down(source, line, name, entry):
        # its beams sweep the base frame the other way round: a mirror about its axis
        first, last = -first, -last
    return laser_beams(name, x, y, yaw, first, last, samples, rmin, rmax)
