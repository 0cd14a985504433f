"""``gridmap inspect``: what a log holds and what ``build`` would make of it.

:func:`describe_log` returns plain data (the ``--json`` output); :func:`render_text` turns it
into the text a person reads. Nothing here prints.

The verdict (``build.ready``, ``build.problem``) is build's own: the description runs the checks
build runs (read, robot, :func:`~gridmap_cli.mapping.pipeline.plan_build`, with build's default
options)
and reports the first error build would stop at, word for word, not a parallel set of rules.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import GridmapError, InputFileError
from gridmap_cli.mapping.pipeline import BuildOptions, plan_build
from gridmap_cli.mapping.selection import Selected, Selection, apply_selection, names_text
from gridmap_cli.poses.odometry_error import travelled
from gridmap_cli.poses.sync import interpolate_pose
from gridmap_cli.readers import LogFormat, recording_sources
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros.recording import RecordingRead, read_recording
from gridmap_cli.readers.ros.topics import TF_TYPES
from gridmap_cli.readers.text.aria_log import LASER_MAX_RANGE_M
from gridmap_cli.records import EPOCH_FROM_NS, PoseTrack, RangeLog, span_text, stamp_text
from gridmap_cli.robot import RangeSensor, RobotDescription, robot_from_log


def describe_log(
    paths: Sequence[Path],
    fmt: LogFormat,
    options: ReadOptions,
    selection: Selection | None = None,
) -> dict[str, Any]:
    """Describe a log of any format (several ROS recordings as one, as build reads them), or the
    part of it ``selection`` chooses. ``fmt`` is the format of the first.

    Raises what the reader raises for a broken CSV/ARIA file, and what
    :func:`~gridmap_cli.mapping.selection.apply_selection` raises for a selection the log cannot
    meet.
    """
    path = paths[0]
    size = sum(_bytes(p) for p in paths)
    out: dict[str, Any] = {"file": " + ".join(map(str, paths)), "format": fmt.name, "bytes": size}
    problem: str | None = None
    mcap: RecordingRead | None = None
    sources = recording_sources(paths, fmt.name if len(paths) == 1 else None)
    if sources is not None:
        mcap = read_recording(sources, options, strict=False, every_topic=True)
        problem = None if mcap.problem is None else str(mcap.problem)
        log = mcap.log
        out["mcap"] = _mcap_part(mcap)
    else:
        log = fmt.read(path, options)
    robot, robot_source, robot_problem = _robot(path, log, options)
    problem = problem or robot_problem  # build reads the log before it loads the robot
    try:
        selected = apply_selection(log, selection or Selection(), robot)
    except InputFileError as exc:  # the log cannot be mapped: described whole, build's error
        problem = problem or str(exc)
        out["selection"], out["notes"] = None, []
    else:
        log = selected.log
        out["selection"] = _selection_part(selection, selected) if selection else None
        out["notes"] = list(selected.notes)
    if problem is None:
        problem = _build_problem(log, robot)
    during = _during_odometry(log)
    out["log"] = _log_part(log, during, robot, mcap.mount_from if mcap is not None else None)
    out["build"] = _build_part(fmt, log, mcap, robot, robot_source, problem)
    return out


def _bytes(path: Path) -> int:
    """A file's size, or the sum of a folder's files (a rosbag2 folder)."""
    if path.is_dir():
        return sum(f.stat().st_size for f in path.iterdir() if f.is_file())
    return path.stat().st_size


def _build_problem(log: RangeLog, robot: RobotDescription | None) -> str | None:
    """The error build would stop at once it has read the log and found the robot, or None.

    Build's own checks with its default options (``--mode standard``, 0.05 m cells): the
    sensors' mounting, readings left after sync, the size of the map.
    """
    try:
        plan_build(log, robot, BuildOptions())
    except GridmapError as exc:
        return str(exc)
    return None


def _selection_part(selection: Selection, selected: Selected) -> dict[str, Any]:
    names = selected.log.sensor_names
    return {
        "sensors": list(selection.sensors),
        "start": selection.start.text if selection.start is not None else None,
        "end": selection.end.text if selection.end is not None else None,
        "start_ns": selected.start_ns,
        "end_ns": selected.end_ns,
        "sensors_selected": len(names),
        "sensors_in_log": selected.sensors_before,
        "sensor_names": names_text(names),
    }


def _during_odometry(log: RangeLog) -> npt.NDArray[np.bool_]:
    """Which readings (shape (N,)) fall within the odometry's time span, as sync decides it."""
    if not len(log.poses):
        return np.zeros(len(log.readings), dtype=bool)
    return interpolate_pose(log.poses, log.readings.stamp_ns)[3]


def _robot(
    path: Path, log: RangeLog, options: ReadOptions
) -> tuple[RobotDescription | None, str | None, str | None]:
    """The robot build would use, where it comes from, and the error build would stop at."""
    if options.robot is not None:
        return options.robot, "--robot", None
    try:
        robot = robot_from_log(path, log.metadata)
    except GridmapError as exc:
        return None, None, str(exc)
    return robot, "the log's robot line" if robot is not None else None, None


def _rate(count: int, span_ns: int) -> float | None:
    return round((count - 1) / (span_ns / 1e9), 3) if count > 1 and span_ns > 0 else None


def _use(topic: str, read: RecordingRead) -> str:
    """What a read does with ``topic``, in words ('' when nothing)."""
    plan = read.plan
    if topic == plan.odom_topic:
        return "odometry"
    truth_from = read.truth_from or ""
    if topic == plan.truth_topic:
        return "ground truth" if topic in truth_from else ""
    if topic == plan.reference_topic and truth_from.startswith(topic):
        return "reference (--pose global)"
    if topic in plan.range_topics:
        return "range readings"
    if topic == plan.sensors_topic:
        return "sensor descriptions"
    if topic in plan.static_topics:
        return "sensor mounting"
    uses = []
    if topic in plan.tf_topics and plan.odom_topic is None:
        uses.append(f"odometry ({plan.odom_frame} -> {read.base_frame})")
    if topic in plan.tf_topics and not plan.static_topics:
        uses.append("sensor mounting")
    if topic in plan.tf_topics and truth_from.startswith("TF "):
        uses.append(f"reference ({truth_from.removeprefix('TF ')})")
    return " + ".join(uses)


def _mcap_part(read: RecordingRead) -> dict[str, Any]:
    survey = read.survey
    span = (survey.end_ns or 0) - (survey.start_ns or 0)
    channels = []
    for c in survey.channels:
        first, last = read.spans.get(c.topic, (0, 0))
        channels.append(
            {
                "topic": c.topic,
                "type": c.type_name,
                "schema_encoding": c.schema_encoding,
                "message_encoding": c.message_encoding,
                "messages": c.count,
                "first_ns": first if c.count else None,
                "last_ns": last if c.count else None,
                "rate_hz": _rate(c.count, last - first),
                "qos": c.qos or None,
                "used_as": _use(c.topic, read),
            }
        )
    return {
        "profile": survey.profile,
        "library": survey.library,
        "indexed": survey.indexed,
        "storage": survey.storage,
        "compression": survey.compression,
        "files": [{"file": f, "bytes": n} for f, n in survey.files],
        "messages": survey.message_count,
        "log_time": None
        if survey.start_ns is None
        else {"start_ns": survey.start_ns, "end_ns": survey.end_ns, "duration_s": span / 1e9},
        "channels": channels,
        "metadata": survey.metadata,
        "tf": [
            {"parent": p, "child": c, "transforms": n}
            for (p, c), n in sorted(read.tf_pairs.items())
        ],
        "static_frames": list(read.static_frames),
    }


def _track_part(track: PoseTrack) -> dict[str, Any] | None:
    n = len(track)
    if n == 0:
        return None
    t = track.stamp_ns
    span = int(t[-1] - t[0])
    distance, rotation = travelled(track)
    return {
        "count": n,
        "start_ns": int(t[0]),
        "end_ns": int(t[-1]),
        "duration_s": span / 1e9,
        "rate_hz": _rate(n, span),
        "distance_m": round(float(distance[-1]), 3),
        "rotation_deg": round(math.degrees(float(rotation[-1])), 1),
        "start_pose": [float(track.x_m[0]), float(track.y_m[0]), float(track.theta_rad[0])],
        "end_pose": [float(track.x_m[-1]), float(track.y_m[-1]), float(track.theta_rad[-1])],
    }


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


def _log_part(
    log: RangeLog,
    valid: npt.NDArray[np.bool_],
    robot: RobotDescription | None,
    mount_from: dict[str, str] | None,
) -> dict[str, Any]:
    r = log.readings
    own = {s.name: s for s in log.sensors or ()}
    theirs = robot.by_name() if robot is not None else {}
    described = [own.get(n) or theirs.get(n) for n in log.sensor_names]
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
    readings: dict[str, Any] | None = None
    if len(r):
        span = int(r.stamp_ns.max() - r.stamp_ns.min())
        inside = int(np.count_nonzero(valid))
        below_min: int | None = None  # as build's sync counts them; None: a sensor is unknown
        if all(s is not None for s in described):
            min_r = np.asarray([s.min_range_m for s in described if s is not None])
            below_min = int(np.count_nonzero(valid & (r.range_m < min_r[r.sensor])))
        readings = {
            "count": len(r),
            "start_ns": int(r.stamp_ns.min()),
            "end_ns": int(r.stamp_ns.max()),
            "duration_s": span / 1e9,
            "rate_hz": _rate(len(r), span),
            "no_echo": sum(s["no_echo"] for s in sensors),
            "during_odometry": inside,
            "below_min_range": below_min,
        }
    return {
        "odometry": _track_part(log.poses),
        "truth": _track_part(log.truth) if log.truth is not None else None,
        "readings": readings,
        "sensors": sensors,
        "metadata": log.metadata,
    }


def _lasers(fmt: LogFormat, log: RangeLog, robot: RobotDescription | None) -> list[dict[str, Any]]:
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


def _build_part(
    fmt: LogFormat,
    log: RangeLog,
    mcap: RecordingRead | None,
    robot: RobotDescription | None,
    robot_source: str | None,
    problem: str | None,
) -> dict[str, Any]:
    if mcap is not None:
        plan = mcap.plan
        if plan.odom_topic is not None:
            channel = mcap.survey.topic(plan.odom_topic)
            odometry = f"{plan.odom_topic} ({channel.type_name if channel else '?'})"
        elif plan.tf_topics:
            odometry = f"TF {plan.odom_frame} -> {mcap.base_frame} on {', '.join(plan.tf_topics)}"
        else:
            odometry = None
        ranges = list(plan.range_topics)
        truth = mcap.truth_from
        frames: dict[str, Any] = {"odom": plan.odom_frame, "base": mcap.base_frame}
        odom_topic = plan.odom_topic
    elif fmt.name == "csv":
        odometry = "columns time, x, y, theta"
        ranges = [f"{len(log.sensor_names)} sensor columns: {' '.join(_ends(log.sensor_names))}"]
        truth = "columns true_x, true_y, true_theta" if log.truth is not None else None
        frames = {}
        odom_topic = None
    elif fmt.name == "carmen":
        odometry = "ODOM lines: the chain of their increments (the robot's own odometry)"
        lasers = sorted({n.rpartition("_")[0] for n in log.sensor_names})
        ranges = [f"{laser} ({sum(n.startswith(laser + '_') for n in log.sensor_names)} beams)"
                  for laser in lasers]  # fmt: skip
        truth = None
        if log.truth is not None:
            truth = log.metadata.get("truth", "reference track").removesuffix(" (--pose global)")
            truth = "reference track: " + truth
        frames = {}
        odom_topic = None
    else:
        odometry = "robot: lines (encoder pose)"
        lasers = [n for n in log.sensor_names if n.startswith("laser")]
        sonars = [n for n in log.sensor_names if not n.startswith("laser")]
        ranges = []
        if sonars:
            ranges.append(f"sonar: lines ({len(sonars)} sonars)")
        if lasers:
            ranges.append(f"sick/scan lines ({len(lasers)} laser beams)")
        truth = "robotGlobal: lines" if log.truth is not None else None
        frames = {}
        odom_topic = None
    mounted = {s.name for s in log.sensors or () if not math.isnan(s.x_m)}
    described_by_log = bool(log.sensor_names) and mounted >= set(log.sensor_names)
    return {
        "odometry": odometry,
        "odometry_topic": odom_topic,
        "frames": frames,
        "ranges": ranges,
        "truth": truth,
        "sensors": len(log.sensor_names),
        "lasers": _lasers(fmt, log, robot),
        "robot": None
        if robot is None
        else {"name": robot.name, "from": robot_source, "needed": not described_by_log},
        "ready": problem is None,
        "problem": problem,
    }


# ------------------------------------------------------------------------------------ text


def _some(items: list[str], limit: int) -> str:
    more = f" and {len(items) - limit} more" if len(items) > limit else ""
    return ", ".join(items[:limit]) + more


def _ends(names: tuple[str, ...]) -> list[str]:
    if len(names) <= 3:
        return list(names)
    return [names[0], "..", names[-1]]


def _n(value: int) -> str:
    return f"{value:,}"


def _hz(value: float | None) -> str:
    if not value:
        return "-"
    return f"{value:,.0f} Hz" if value >= 100 else f"{value:.3g} Hz"


def _metres(value: float) -> str:
    """A length to the millimetre, without trailing zeros (4.335, 0.15, 80)."""
    return f"{round(value, 3):g}"


def _range_text(sensor: dict[str, Any]) -> str:
    if "max_range_m" not in sensor:
        return "?"
    return f"{_metres(sensor['min_range_m'])}-{_metres(sensor['max_range_m'])}"


def _unused(channel: dict[str, Any], build: dict[str, Any]) -> str:
    """'-', with the reason when a TF channel is left unread (odometry from a pose topic)."""
    if channel["type"] in TF_TYPES and build.get("odometry_topic"):
        return f"- (odometry is {build['odometry_topic']})"
    return "-"


def _pose_text(pose: list[float]) -> str:
    return f"({pose[0]:.3f} m, {pose[1]:.3f} m, {math.degrees(pose[2]):.1f} deg)"


def _table(rows: list[list[str]]) -> list[str]:
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return ["  " + "  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip()
            for row in rows]  # fmt: skip


def _size(size: int) -> str:
    return f"{size / 1e6:.1f} MB" if size >= 100_000 else f"{_n(size)} bytes"


def render_text(d: dict[str, Any]) -> str:
    """The description as text for people, one section per subject."""
    lines: list[str] = []
    head = f"{d['file']}: {d['format'].upper()} log, {_size(d['bytes'])}"
    mcap = d.get("mcap")
    if mcap is not None:
        profile = f"profile '{mcap['profile']}'" if mcap["profile"] else "no profile"
        head += f"; {profile}, written by {mcap['library'] or '?'}"
    lines.append(head)
    if mcap is not None:
        lt = mcap["log_time"]
        if lt is None:
            lines.append("  no messages")
        else:
            lines.append(
                f"  {_n(mcap['messages'])} messages, log time "
                f"{span_text(lt['start_ns'], lt['end_ns'])}"
            )
        storage = f"  storage {mcap['storage'] or '?'}, compression {mcap['compression'] or '?'}"
        if len(mcap["files"]) > 1:
            names = [f"{Path(f['file']).name} ({_size(f['bytes'])})" for f in mcap["files"]]
            storage += f"; {len(names)} files: {_some(names, 4)}"
        lines.append(storage)
        if not mcap["indexed"]:
            lines.append("  no index: the file is read from start to end")
        lines += ["", "Channels:"]
        with_qos = any(c["qos"] for c in mcap["channels"])
        rows = [["topic", "type", "encoding", "messages", "rate", "gridmap uses it as"]]
        rows[0] += ["QoS"] if with_qos else []
        for c in mcap["channels"]:
            rows.append([c["topic"], c["type"] or "(no schema)", c["message_encoding"],
                         _n(c["messages"]), _hz(c["rate_hz"]),
                         c["used_as"] or _unused(c, d["build"])])  # fmt: skip
            rows[-1] += [c["qos"] or "-"] if with_qos else []
        lines += _table(rows)
        if mcap["tf"]:
            pairs = [f"{t['parent']} -> {t['child']} ({_n(t['transforms'])})" for t in mcap["tf"]]
            lines.append(f"  TF read: {_some(pairs, 6)}")
        if mcap["static_frames"]:
            frames = mcap["static_frames"]
            base = d["build"]["frames"]["base"]
            lines.append(
                f"  mounting known for {len(frames)} frame{'s' if len(frames) > 1 else ''} "
                f"below '{base}': {_some(frames, 6)}"
            )
    lines += _selection_lines(d.get("selection"), d.get("notes") or [])
    log = d["log"]
    for key, title in (("odometry", "Odometry"), ("truth", "Ground truth / reference")):
        track = log[key]
        lines.append("")
        if track is None:
            lines.append(f"{title}: none")
            continue
        lines.append(
            f"{title}: {_n(track['count'])} poses, "
            f"{span_text(track['start_ns'], track['end_ns'])}, {_hz(track['rate_hz'])}"
        )
        clock = _clock_note(track["start_ns"], mcap)
        if clock:
            lines.append(clock)
        lines.append(
            f"  travelled {track['distance_m']:.2f} m and turned {track['rotation_deg']:.0f} deg, "
            f"from {_pose_text(track['start_pose'])} to {_pose_text(track['end_pose'])}"
        )
    readings = log["readings"]
    lines.append("")
    if readings is None:
        lines.append("Range readings: none")
    else:
        lines.append(
            f"Range readings: {_n(readings['count'])} ({_n(readings['no_echo'])} at maximum "
            "range: no echo), "
            f"{span_text(readings['start_ns'], readings['end_ns'])}, {_hz(readings['rate_hz'])}"
        )
        during = f"  {_n(readings['during_odometry'])} of them during the odometry's time span"
        below = readings.get("below_min_range")
        if below:
            mapped = readings["during_odometry"] - below
            during += (
                f", {_n(below)} of these below their sensor's minimum range: "
                f"build maps {_n(mapped)}"
            )
        lines.append(during)
    lines += _sensor_lines(log["sensors"])
    if log["metadata"]:
        lines += ["", "Log header: " + ", ".join(f"{k}: {v}" for k, v in log["metadata"].items())]
    b = d["build"]
    lines += ["", "What build would use:"]
    lines.append(f"  odometry  {b['odometry'] or 'none'}")
    if b["frames"] and mcap is not None and (mcap["tf"] or mcap["static_frames"]):
        lines.append(f"  frames    odometry '{b['frames']['odom']}', base '{b['frames']['base']}'")
    lines.append(f"  ranges    {_some(b['ranges'], 6) or 'none'}")
    for laser in b["lasers"]:
        lines.append(f"  laser     {_laser_text(laser)}")
    if b["truth"]:
        lines.append(f"  truth     {b['truth']} (with --pose global)")
    lines.append(f"  sensors   {b['sensors']}")
    robot = b["robot"]
    if robot is None:
        lines.append("  robot     none")
    else:
        lines.append(f"  robot     {robot['name']} ({robot['from']})")
        if not robot["needed"]:
            lines[-1] += f"; not needed: the log describes all {b['sensors']} sensors"
    if b["ready"]:
        lines.append("  -> ready to build")
    else:
        # the file name and topic list are shown above already
        problem = b["problem"].removeprefix(f"{d['file']}: ").split("; topics: ")[0]
        lines.append(f"  -> build would fail: {problem}")
    return "\n".join(lines)


def _laser_text(laser: dict[str, Any]) -> str:
    """``laser1: 181 beams, 0.02-8 m`` and where the range comes from when not the log."""
    beams = laser["beams"]
    text = (
        f"{laser['laser']}: {beams} beam{'s' if beams != 1 else ''}, "
        f"{_metres(laser['min_range_m'])}-{_metres(laser['max_range_m'])} m"
    )
    source = laser["range_from"]
    if source == "assumed":
        return text + " (the log gives no range: gridmap's default)"
    return text if source == "log" else f"{text} (from the {source})"


def _selection_lines(sel: dict[str, Any] | None, notes: list[str]) -> list[str]:
    lines = [f"Warning: {note}" for note in notes]
    if sel is None:
        return lines
    flags = [f"--sensors '{p}'" for p in sel["sensors"]]
    flags += [f"--{k} {sel[k]}" for k in ("start", "end") if sel[k] is not None]
    lines += ["", f"Selection ({' '.join(flags)}): the rest of this description is of it"]
    lines.append(
        f"  sensors   {sel['sensors_selected']} of {sel['sensors_in_log']}: "
        f"{sel['sensor_names'] or 'none'}"
    )
    if sel["start_ns"] is not None or sel["end_ns"] is not None:
        lo = stamp_text(sel["start_ns"]) if sel["start_ns"] is not None else "the start"
        hi = stamp_text(sel["end_ns"]) if sel["end_ns"] is not None else "the end"
        lines.append(f"  readings  from {lo} to {hi} (not including it)")
    return lines


def _yaw_text(s: dict[str, Any]) -> str:
    m = s["mounting"]
    if not m:
        return "?"
    if s.get("_last_yaw") is not None:
        return f"{m['yaw_deg']:.1f}..{s['_last_yaw']:.1f}"
    return f"{m['yaw_deg']:.1f}"


def _clock_note(first_ns: int, mcap: dict[str, Any] | None) -> str:
    """A note when message stamps and log times are on different clocks (simulation time)."""
    if mcap is None or mcap["log_time"] is None:
        return ""
    if (first_ns >= EPOCH_FROM_NS) == (mcap["log_time"]["start_ns"] >= EPOCH_FROM_NS):
        return ""
    return (
        "  (stamps are the messages' header stamps, on another clock than the log time, "
        "e.g. simulation time)"
    )


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


def _sensor_lines(sensors: list[dict[str, Any]]) -> list[str]:
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
            _n(s["readings"]),
            _n(s["no_echo"]),
            s["mounting_from"],
        ])  # fmt: skip
    lines += _table(rows)
    if len(sensors) > 20:
        lines.insert(-4, f"  ... {len(sensors) - 12} more ...")
    return lines
