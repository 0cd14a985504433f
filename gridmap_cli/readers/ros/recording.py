"""ROS recordings, one or several files, read into the canonical record stream.

A recording is one or more sources: MCAP files (:mod:`~gridmap_cli.readers.ros.mcap.log`), ROS 1
bags and rosbag2 folders (:mod:`~gridmap_cli.readers.ros.bag.log`). Each source surveys its topics
and
yields its messages in log-time order; several sources are merged by log time into one stream
(robots often record odometry and sensors into separate bags), so the topic plan and the message
accumulator see one recording whatever the containers were.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from gridmap_cli.errors import GridmapError, InputFileError
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros.batches import add_columns
from gridmap_cli.readers.ros.mcap.bulk import Batch, bulk_enabled
from gridmap_cli.readers.ros.mcap.channels import METADATA_NAME
from gridmap_cli.readers.ros.messages import MessageAccumulator
from gridmap_cli.readers.ros.topics import ChannelInfo, Plan, Refusals, Survey, plan_topics
from gridmap_cli.records import RangeLog

#: One message: (file, topic, folded type name, log time in ns, decoded message or None).
#: The message is None for topics that were not asked for (read only for their time spans).
Message = tuple[str, str, str, int, Any]


class RecordingSource(Protocol):
    """One file (or rosbag2 folder) of a recording."""

    path: Path

    def survey(self) -> Survey:
        """The source's topics, types, counts and time span."""
        ...

    def messages(self, topics: Sequence[str], every_topic: bool) -> Iterator[Message]:
        """Messages in log-time order: those of ``topics`` decoded; with ``every_topic`` also
        the others, undecoded (None)."""
        ...


@dataclass(frozen=True)
class RecordingRead:
    """A read recording: the canonical log, the survey, the topics and base frame chosen."""

    log: RangeLog
    survey: Survey
    plan: Plan
    base_frame: str
    tf_pairs: dict[tuple[str, str], int]  # (parent, child) -> transforms seen on non-static TF
    static_frames: tuple[str, ...]  # frames with a static transform below the base frame
    mount_from: dict[str, str]  # sensor frame -> where its mounting came from: TF, robot, unknown
    problem: GridmapError | None  # lenient read: the error a strict read raises, if any
    spans: dict[str, tuple[int, int]]  # topic -> first and last log time (ns) of the messages read
    truth_from: str | None  # where the reference track came from: a topic or a TF chain
    problems: tuple[GridmapError, ...] = ()  # lenient read: every error, ``problem`` first
    mounts_only: bool = True  # every problem is a sensor's unknown mounting


def merge_surveys(surveys: Sequence[Survey]) -> Survey:
    """One survey of several files: their topics side by side, counts of a shared topic summed.

    A topic that two files hold with different message types is an error naming both.
    """
    if len(surveys) == 1:
        return surveys[0]
    channels: dict[str, ChannelInfo] = {}
    owner: dict[str, str] = {}
    for survey in surveys:
        for c in survey.channels:
            known = channels.get(c.topic)
            if known is None:
                channels[c.topic] = c
                owner[c.topic] = survey.path
            elif known.type_name != c.type_name:
                raise InputFileError(
                    survey.path,
                    f"topic {c.topic} is {c.type_name or 'untyped'} here but "
                    f"{known.type_name or 'untyped'} in {owner[c.topic]}: the recordings do not "
                    "belong together",
                )
            else:
                channels[c.topic] = ChannelInfo(
                    c.topic,
                    c.type_name,
                    c.schema_encoding,
                    c.message_encoding,
                    known.count + c.count,
                    known.qos or c.qos,
                )
    starts = [s.start_ns for s in surveys if s.start_ns is not None]
    ends = [s.end_ns for s in surveys if s.end_ns is not None]
    metadata: dict[str, dict[str, str]] = {}
    for survey in surveys:
        for name, values in survey.metadata.items():
            metadata.setdefault(name, {}).update(values)
    return Survey(
        path=" + ".join(s.path for s in surveys),
        profile=", ".join(dict.fromkeys(s.profile for s in surveys)),
        library=", ".join(dict.fromkeys(s.library for s in surveys)),
        channels=tuple(channels.values()),
        start_ns=min(starts) if starts else None,
        end_ns=max(ends) if ends else None,
        message_count=sum(s.message_count for s in surveys),
        metadata=metadata,
        indexed=all(s.indexed for s in surveys),
        storage=", ".join(dict.fromkeys(s.storage for s in surveys if s.storage)),
        compression=", ".join(
            dict.fromkeys(c for s in surveys for c in s.compression.split(", ") if c)
        ),
        files=tuple(f for s in surveys for f in s.files),
    )


def _first(batch: Batch, column: str) -> int:
    return int(batch.columns.arrays[column][0])


def read_recording(
    sources: Sequence[RecordingSource],
    options: ReadOptions | None = None,
    strict: bool = True,
    every_topic: bool = False,
    ranges_apart: Callable[[MessageAccumulator, Plan], None] | None = None,
) -> RecordingRead:
    """Read one or several recording files as one recording.

    ``strict=False`` (for ``inspect``) reads what is there where a strict read raises: no
    odometry gives an empty track, a sensor with unknown mounting a NaN mounting pose, and
    :attr:`RecordingRead.problem` is the error the strict read raises. Damaged data, malformed
    messages and bad topic flags raise in both modes. ``every_topic`` also goes through the
    messages of the topics gridmap does not use (without decoding them), for their time spans.
    ``ranges_apart`` reads the plan's range topics into the accumulator itself, first (a
    streamed read, :mod:`~gridmap_cli.readers.ros.mcap.stream`); the read leaves them alone.
    """
    opts = options or ReadOptions()
    refusals = Refusals(strict)
    survey = merge_surveys([s.survey() for s in sources])
    plan = plan_topics(survey, opts, refusals)
    acc = MessageAccumulator(survey.path, plan, opts.robot, refusals)
    acc.laser_mount = opts.laser_mount
    spans: dict[str, list[int]] = {}
    topics = plan.topics()
    if ranges_apart is not None:
        ranges_apart(acc, plan)  # range state is the range topics' alone: order does not matter
        topics = [t for t in topics if t not in plan.range_topics]
    batches: list[tuple[int, int, int, Batch]] = []
    rest: list[Sequence[str]] = []
    for i, source in enumerate(sources):
        bulk = getattr(source, "bulk", None)
        if bulk is None or every_topic or not bulk_enabled():
            rest.append(topics)
            continue
        done, left = bulk(topics)
        batches += [(_first(b, "log_ns"), i, _first(b, "pos"), b) for b in done]
        del done  # the batches list alone holds them: each goes once added
        rest.append(left)
    # a channel decoded in bulk joins the stream where its first message would have (ties: as
    # the merge orders them, by file, then by place in the file); each is let go once added
    batches.sort(key=lambda entry: entry[:3], reverse=True)

    def next_batch() -> Batch | None:
        return batches.pop()[3] if batches else None

    batch = next_batch()

    def add_batch(b: Batch) -> None:
        log_ns = b.columns.arrays["log_ns"]
        first, last = int(log_ns[0]), int(log_ns[-1])
        span = spans.setdefault(b.topic, [first, last])
        span[0], span[1] = min(span[0], first), max(span[1], last)
        add_columns(acc, b.source, b.topic, b.type_name, b.columns)

    streams = [s.messages(t, every_topic) for s, t in zip(sources, rest, strict=True)]
    merged = streams[0] if len(streams) == 1 else heapq.merge(*streams, key=lambda m: m[3])
    for path, topic, type_name, log_time, msg in merged:
        while batch is not None and int(batch.columns.arrays["log_ns"][0]) <= log_time:
            add_batch(batch)
            batch = next_batch()
        span = spans.get(topic)
        if span is None:
            spans[topic] = [log_time, log_time]
        else:
            span[1] = log_time  # log-time order: the latest so far
        if msg is not None:
            acc.add(path, topic, type_name, log_time, msg)
    while batch is not None:
        add_batch(batch)
        batch = next_batch()
    log = acc.finish(survey.metadata.get(METADATA_NAME, {}))
    base = acc.base_frame()
    below = tuple(f for f in acc.tree.order if acc.tree.lookup(base, f) is not None)
    return RecordingRead(
        log,
        survey,
        plan,
        base,
        dict(acc.tf_pairs),
        below,
        acc.mount_from,
        refusals.first,
        {topic: (first, last) for topic, (first, last) in spans.items()},
        acc.truth_from,
        tuple(refusals.errors),
        refusals.mounts_only,
    )
