"""A ROS recording (MCAP, bag, rosbag2, several as one): its files, channels, TF and frames.

:func:`recording_part` is the ``mcap`` part of the description (the same for every container);
:func:`recording_head` and :func:`recording_lines` are its text, under the file's first line.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from gridmap_cli.describe.text import hz, number, size_text, some, table
from gridmap_cli.describe.tracks import rate_hz
from gridmap_cli.readers.ros.recording import RecordingRead
from gridmap_cli.readers.ros.topics import TF_TYPES
from gridmap_cli.records import span_text


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


def recording_part(read: RecordingRead) -> dict[str, Any]:
    """The recording's survey (files, channels with their counts and rates, TF pairs read)."""
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
                "rate_hz": rate_hz(c.count, last - first),
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


def _unused(channel: dict[str, Any], build: dict[str, Any]) -> str:
    """'-', with the reason when a TF channel is left unread (odometry from a pose topic)."""
    if channel["type"] in TF_TYPES and build.get("odometry_topic"):
        return f"- (odometry is {build['odometry_topic']})"
    return "-"


def recording_head(mcap: dict[str, Any]) -> str:
    """What the file's first line says of a recording: its profile and the library writing it."""
    profile = f"profile '{mcap['profile']}'" if mcap["profile"] else "no profile"
    return f"; {profile}, written by {mcap['library'] or '?'}"


def recording_lines(mcap: dict[str, Any], build: dict[str, Any]) -> list[str]:
    """Messages, storage, the channel table and the TF read; ``build`` says what is unused."""
    lines: list[str] = []
    lt = mcap["log_time"]
    if lt is None:
        lines.append("  no messages")
    else:
        lines.append(
            f"  {number(mcap['messages'])} messages, log time "
            f"{span_text(lt['start_ns'], lt['end_ns'])}"
        )
    storage = f"  storage {mcap['storage'] or '?'}, compression {mcap['compression'] or '?'}"
    if len(mcap["files"]) > 1:
        names = [f"{Path(f['file']).name} ({size_text(f['bytes'])})" for f in mcap["files"]]
        storage += f"; {len(names)} files: {some(names, 4)}"
    lines.append(storage)
    if not mcap["indexed"]:
        lines.append("  no index: the file is read from start to end")
    lines += ["", "Channels:"]
    with_qos = any(c["qos"] for c in mcap["channels"])
    rows = [["topic", "type", "encoding", "messages", "rate", "gridmap uses it as"]]
    rows[0] += ["QoS"] if with_qos else []
    for c in mcap["channels"]:
        rows.append([c["topic"], c["type"] or "(no schema)", c["message_encoding"],
                     number(c["messages"]), hz(c["rate_hz"]),
                     c["used_as"] or _unused(c, build)])  # fmt: skip
        rows[-1] += [c["qos"] or "-"] if with_qos else []
    lines += table(rows)
    if mcap["tf"]:
        pairs = [f"{t['parent']} -> {t['child']} ({number(t['transforms'])})" for t in mcap["tf"]]
        lines.append(f"  TF read: {some(pairs, 6)}")
    if mcap["static_frames"]:
        frames = mcap["static_frames"]
        base = build["frames"]["base"]
        lines.append(
            f"  mounting known for {len(frames)} frame{'s' if len(frames) > 1 else ''} "
            f"below '{base}': {some(frames, 6)}"
        )
    return lines
