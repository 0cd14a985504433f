"""The log's sensors: how each is mounted and where that comes from, its readings, its lasers.

:func:`sensor_parts` is the ``log.sensors`` part of the description and :func:`lasers_part`
the ``build.lasers`` one; :func:`sensor_lines` and :func:`laser_text` their text (a laser's
beams folded into one row).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gridmap_cli.describe.text import metres, number, table
from gridmap_cli.readers import LogFormat
from gridmap_cli.readers.text.aria_log import LASER_MAX_RANGE_M
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RangeSensor, RobotDescription


def described_sensors(log: RangeLog, robot: RobotDescription | None) -> list[RangeSensor | None]:
    """Each of ``log.sensor_names`` as the log, else the robot, describes it (None: neither)."""
    own = {s.name: s for s in log.sensors or ()}
    theirs = robot.by_name() if robot is not None else {}
    return [own.get(n) or theirs.get(n) for n in log.sensor_names]


def _sensor_part(
    name: str,
    own: RangeSensor | None,
    robot_sensor: RangeSensor | None,
    count: int,
    no_echo: int,
    source: str | None,
) -> dict[str, Any]:
    sensor = own or robot_sensor
    entry: dict[str, Any] = {"name": name, "readings": count, "no_echo": no_echo}
    if sensor is None or math.isnan(sensor.x_m):
        entry["mounting"] = None
        entry["mounting_from"] = "unknown"
    else:
        entry["mounting"] = {
            "x_m": round(sensor.x_m, 6),
            "y_m": round(sensor.y_m, 6),
            "yaw_deg": round(math.degrees(sensor.yaw_rad), 3),
        }
        entry["mounting_from"] = source or ("log" if own is not None else "robot")
    if sensor is not None:
        entry.update(
            kind=sensor.kind,
            beam_width_deg=round(math.degrees(sensor.beam_width_rad), 3),
            min_range_m=round(sensor.min_range_m, 6),
            max_range_m=round(sensor.max_range_m, 6),
        )
    return entry


def sensor_parts(
    log: RangeLog,
    robot: RobotDescription | None,
    mount_from: dict[str, str] | None,
    described: list[RangeSensor | None],
) -> list[dict[str, Any]]:
    """One entry per sensor: its mounting and its source, its readings and those without echo.

    ``mount_from``: a recording's frame -> where its mounting came from; ``described``: what
    :func:`described_sensors` gives.
    """
    r = log.readings
    own = {s.name: s for s in log.sensors or ()}
    theirs = robot.by_name() if robot is not None else {}
    n = len(log.sensor_names)
    counts = np.bincount(r.sensor, minlength=n)
    # no echo: at or beyond the sensor's maximum range; none counted for an unknown sensor
    max_r = np.asarray([s.max_range_m if s else np.inf for s in described], dtype=np.float64)
    known = np.asarray([s is not None for s in described], dtype=bool)
    echo_less = known[r.sensor] & (r.range_m >= max_r[r.sensor])
    no_echoes = np.bincount(r.sensor[echo_less], minlength=n)
    sensors = []
    for i, name in enumerate(log.sensor_names):
        no_echo = int(no_echoes[i])
        frame = name if name in (mount_from or {}) else name.rpartition("_")[0]
        source = (mount_from or {}).get(frame)
        sensors.append(
            _sensor_part(name, own.get(name), theirs.get(name), int(counts[i]), no_echo, source)
        )
    return sensors


def lasers_part(
    fmt: LogFormat, log: RangeLog, robot: RobotDescription | None
) -> list[dict[str, Any]]:
    """Each scanning laser build would map with (beams ``<laser>_<i>``): beams and range.

    ``range_from`` says where the range comes from: the log, the robot description, or
    ``assumed`` for an ARIA log without gridmap's range lines (ARIA writes none).
    """
    own = {s.name: s for s in log.sensors or () if not math.isnan(s.x_m)}
    theirs = robot.by_name() if robot is not None else {}
    lasers: dict[str, list[tuple[RangeSensor, str]]] = {}
    for name in log.sensor_names:
        sensor, source = (own[name], "log") if name in own else (theirs.get(name), "robot")
        if sensor is not None and sensor.kind == "laser":
            lasers.setdefault(name.rpartition("_")[0] or name, []).append((sensor, source))
    out = []
    for frame, beams in lasers.items():
        rmin = min(s.min_range_m for s, _ in beams)
        rmax = max(s.max_range_m for s, _ in beams)
        sources = sorted({source for _, source in beams})
        source = sources[0] if len(sources) == 1 else "log and robot"
        if fmt.name == "aria" and source == "log" and (rmin, rmax) == (0.0, LASER_MAX_RANGE_M):
            source = "assumed"
        out.append(
            {
                "laser": frame,
                "beams": len(beams),
                "min_range_m": round(rmin, 6),
                "max_range_m": round(rmax, 6),
                "range_from": source,
            }
        )
    return out


def laser_text(laser: dict[str, Any]) -> str:
    """``laser1: 181 beams, 0.02-8 m`` and where the range comes from when not the log."""
    beams = laser["beams"]
    text = (
        f"{laser['laser']}: {beams} beam{'s' if beams != 1 else ''}, "
        f"{metres(laser['min_range_m'])}-{metres(laser['max_range_m'])} m"
    )
    source = laser["range_from"]
    if source == "assumed":
        return text + " (the log gives no range: gridmap's default)"
    return text if source == "log" else f"{text} (from the {source})"


def _range_text(sensor: dict[str, Any]) -> str:
    if "max_range_m" not in sensor:
        return "?"
    return f"{metres(sensor['min_range_m'])}-{metres(sensor['max_range_m'])}"


def _yaw_text(s: dict[str, Any]) -> str:
    m = s["mounting"]
    if not m:
        return "?"
    if s.get("_last_yaw") is not None:
        return f"{m['yaw_deg']:.1f}..{s['_last_yaw']:.1f}"
    return f"{m['yaw_deg']:.1f}"


def _group_beams(sensors: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Laser beams ``<laser>_0`` .. ``<laser>_<n-1>`` folded into one row per laser."""
    out: list[dict[str, Any]] = []
    for s in sensors:
        prefix, _, index = s["name"].rpartition("_")
        last = out[-1] if out else None
        if (
            s.get("kind") == "laser"
            and last is not None
            and last.get("kind") == "laser"
            and last.get("_prefix") == prefix
            and index.isdigit()
        ):
            last["_count"] += 1
            last["readings"] += s["readings"]
            last["no_echo"] += s["no_echo"]
            last["_last_yaw"] = s["mounting"]["yaw_deg"] if s["mounting"] else None
            last["name"] = f"{prefix}_{last['_first']}..{index} ({last['_count']} beams)"
            continue
        entry = dict(s)
        if s.get("kind") == "laser" and index.isdigit():
            entry.update(_prefix=prefix, _first=index, _count=1, _last_yaw=None)
        out.append(entry)
    return out


def sensor_lines(sensors: list[dict[str, Any]]) -> list[str]:
    """The sensors section: one table row per sensor (per laser), long tables cut short."""
    lines = ["", f"Sensors: {len(sensors) or 'none'}"]
    if not sensors:
        return lines
    sensors = _group_beams(sensors)
    rows = [["name", "kind", "x m", "y m", "yaw deg", "beam deg", "range m", "readings",
             "no echo", "mounting from"]]  # fmt: skip
    shown = sensors if len(sensors) <= 20 else sensors[:8] + sensors[-4:]
    for s in shown:
        m = s["mounting"]
        rows.append([
            s["name"],
            s.get("kind", "?"),
            f"{m['x_m']:.3f}" if m else "?",
            f"{m['y_m']:.3f}" if m else "?",
            _yaw_text(s),
            f"{s['beam_width_deg']:.1f}" if "beam_width_deg" in s else "?",
            _range_text(s),
            number(s["readings"]),
            number(s["no_echo"]),
            s["mounting_from"],
        ])  # fmt: skip
    lines += table(rows)
    if len(sensors) > 20:
        lines.insert(-4, f"  ... {len(sensors) - 12} more ...")
    return lines
