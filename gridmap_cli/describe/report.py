"""The whole description: :func:`describe_log` gathers every part, :func:`render_text` puts
their sections together in the order a person reads them.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.describe.recording import recording_head, recording_lines, recording_part
from gridmap_cli.describe.selection import selection_lines, selection_part
from gridmap_cli.describe.sensors import described_sensors, sensor_lines, sensor_parts
from gridmap_cli.describe.text import size_text
from gridmap_cli.describe.tracks import (
    during_odometry,
    readings_lines,
    readings_part,
    track_lines,
    track_part,
)
from gridmap_cli.describe.verdict import build_lines, build_part, build_problem, robot_for
from gridmap_cli.errors import InputFileError
from gridmap_cli.mapping.selection import Selection, apply_selection
from gridmap_cli.readers import LogFormat, recording_sources
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros.recording import RecordingRead, read_recording
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RobotDescription


def describe_log(
    paths: Sequence[Path],
    fmt: LogFormat,
    options: ReadOptions,
    selection: Selection | None = None,
    held: tuple[RangeLog, int] | None = None,
) -> dict[str, Any]:
    """Describe a log of any format (several ROS recordings as one, as build reads them), or the
    part of it ``selection`` chooses. ``fmt`` is the format of the first. ``held`` is a log
    already read (standard input) and its size in bytes; ``paths`` then holds its name.

    Raises what the reader raises for a broken CSV/ARIA file, and what
    :func:`~gridmap_cli.mapping.selection.apply_selection` raises for a selection the log cannot
    meet.
    """
    path = paths[0]
    size = held[1] if held is not None else sum(_bytes(p) for p in paths)
    out: dict[str, Any] = {"file": " + ".join(map(str, paths)), "format": fmt.name, "bytes": size}
    problems: list[str] = []  # every error build would meet, in the order it would meet them
    mcap: RecordingRead | None = None
    sources = None if held else recording_sources(paths, fmt.name if len(paths) == 1 else None)
    if held is not None:
        log = held[0]
    elif sources is not None:
        mcap = read_recording(sources, options, strict=False, every_topic=True)
        problems += [str(p) for p in mcap.problems]
        log = mcap.log
        out["mcap"] = recording_part(mcap)
    else:
        log = fmt.read(path, options)
    robot, robot_source, robot_problem = robot_for(path, log, options)
    if robot_problem is not None:  # build reads the log before it loads the robot
        problems.append(robot_problem)
    try:
        selected = apply_selection(log, selection or Selection(), robot)
    except InputFileError as exc:  # the log cannot be mapped: described whole, build's error
        problems.append(str(exc))
        out["selection"], out["notes"] = None, []
    else:
        log = selected.log
        out["selection"] = selection_part(selection, selected) if selection else None
        out["notes"] = list(selected.notes)
        # build's own checks on what was read: a recording with a laser of unknown mounting
        # may also be one whose recordings do not overlap in time (after other problems they
        # would only say again what those said)
        if not problems or (mcap is not None and mcap.mounts_only and not robot_problem):
            later = build_problem(log, robot)
            if later is not None and later not in problems:
                problems.append(later)
    during = during_odometry(log)
    out["log"] = _log_part(log, during, robot, mcap.mount_from if mcap is not None else None)
    out["build"] = build_part(fmt, log, mcap, robot, robot_source, problems)
    return out


def _bytes(path: Path) -> int:
    """A file's size, or the sum of a folder's files (a rosbag2 folder)."""
    if path.is_dir():
        return sum(f.stat().st_size for f in path.iterdir() if f.is_file())
    return path.stat().st_size


def _log_part(
    log: RangeLog,
    valid: npt.NDArray[np.bool_],
    robot: RobotDescription | None,
    mount_from: dict[str, str] | None,
) -> dict[str, Any]:
    described = described_sensors(log, robot)
    sensors = sensor_parts(log, robot, mount_from, described)
    no_echo = sum(s["no_echo"] for s in sensors)
    return {
        "odometry": track_part(log.poses),
        "truth": track_part(log.truth) if log.truth is not None else None,
        "readings": readings_part(log.readings, valid, described, no_echo),
        "sensors": sensors,
        "metadata": log.metadata,
    }


#: Width the text description's long lines are wrapped to.
TEXT_WIDTH = 100


def header_lines(metadata: dict[str, str]) -> list[str]:
    """The log's header as text: one line when it fits in :data:`TEXT_WIDTH` columns
    ("Log header: robot: p3at, seed: 7"); else one key a line, its value wrapped beside it (a
    CARMEN log's notes on its odometry, stamps and laser run to 600 characters)."""
    line = "Log header: " + ", ".join(f"{k}: {v}" for k, v in metadata.items())
    if len(line) <= TEXT_WIDTH:
        return [line]
    key_width = max(len(k) for k in metadata)
    indent = " " * (2 + key_width + 2)
    lines = ["Log header:"]
    for key, value in metadata.items():
        wrapped = textwrap.wrap(
            str(value), TEXT_WIDTH, initial_indent=f"  {key:<{key_width}}  ",
            subsequent_indent=indent, break_on_hyphens=False,
        ) or [f"  {key}"]  # fmt: skip
        lines += wrapped
    return lines


def render_text(d: dict[str, Any]) -> str:
    """The description as text for people, one section per subject."""
    head = f"{d['file']}: {d['format'].upper()} log, {size_text(d['bytes'])}"
    mcap = d.get("mcap")
    if mcap is not None:
        head += recording_head(mcap)
    lines = [head]
    if mcap is not None:
        lines += recording_lines(mcap, d["build"])
    lines += selection_lines(d.get("selection"), d.get("notes") or [])
    log = d["log"]
    lines += track_lines(log, mcap)
    lines += readings_lines(log["readings"])
    lines += sensor_lines(log["sensors"])
    if log["metadata"]:
        lines += ["", *header_lines(log["metadata"])]
    lines += build_lines(d)
    return "\n".join(lines)
