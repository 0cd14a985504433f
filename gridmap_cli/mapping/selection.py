"""Choosing part of a log: some of its sensors (``--sensors``), a time window (``--start``,
``--end``), and leaving out CSV columns that are no range sensor.

Works on the canonical :class:`~gridmap_cli.records.RangeLog` after any reader, so every format
(CSV, ARIA, MCAP and readers to come) is selected from alike. Pure functions: they return a new
log and, separately, the notes a user should read (``Selected.notes``); nothing here prints.

A selected log is the log that would have been recorded with only those sensors, in that time:
``sensor_names`` keeps the chosen names in their order and ``readings.sensor`` is re-indexed, so
sync and the robot description look-up see nothing else. The pose tracks keep the poses within
the window and the ones just outside it, so readings at the window's edges still interpolate.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from fnmatch import fnmatchcase

import numpy as np

from gridmap_cli.errors import InputFileError, UsageError
from gridmap_cli.mapping.stamps import stamp_problem
from gridmap_cli.readers.text.csv_log import seconds_to_ns
from gridmap_cli.records import EPOCH_FROM_NS, PoseTrack, RangeLog, RangeReadings, span_text
from gridmap_cli.records import stamp_text as _stamp_text
from gridmap_cli.robot import RobotDescription

#: A ``--sensors`` pattern starting with this leaves the sensors it matches out.
EXCLUDE = "!"

_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)
# the fraction of an ISO time, read here to the nanosecond (datetime keeps microseconds)
_ISO_FRACTION = re.compile(r"^(.*\d{2}:\d{2}:\d{2})[.,](\d+)(.*)$")
_NUMBERED = re.compile(r"^(.*?)(\d+)$")


@dataclass(frozen=True)
class TimeBound:
    """One end of a time window as given: seconds from the log's start, or a clock time.

    ``offset_ns``: nanoseconds after the log's first stamp; ``epoch_ns``: Unix time in ns.
    Exactly one of them is set. ``flag`` and ``text`` are what the user typed, for messages.
    """

    flag: str
    text: str
    offset_ns: int | None = None
    epoch_ns: int | None = None

    def stamp_ns(self, log: RangeLog, origin_ns: int) -> int:
        """The bound as a stamp of ``log``, whose first stamp is ``origin_ns``."""
        if self.offset_ns is not None:
            return origin_ns + self.offset_ns
        assert self.epoch_ns is not None
        if origin_ns < EPOCH_FROM_NS:
            raise UsageError(
                f"{self.flag} {self.text}: {log.source} is not stamped with clock times (it "
                f"spans {span_text(*_log_span(log))}); give seconds from its start"
            )
        return self.epoch_ns


def parse_time(text: str, flag: str) -> TimeBound:
    """``--start``/``--end`` text: seconds from the log's start (``12.5``) or ISO 8601.

    ISO times may carry a fraction (read to the nanosecond) and a UTC offset (``Z``,
    ``+02:00``); a time without an offset is UTC. Raises :class:`UsageError` for anything else.
    """
    value = text.strip()
    try:
        offset = seconds_to_ns(value)
    except ValueError as exc:
        if not str(exc).startswith("not a number"):  # a number, but no stamp holds it
            raise UsageError(f"{flag} {text}: {exc}") from None
    else:
        if offset < 0:
            raise UsageError(f"{flag} {text}: seconds from the log's start cannot be negative")
        return TimeBound(flag, text, offset_ns=offset)
    fraction_ns = 0
    match = _ISO_FRACTION.match(value)
    if match:
        value = match.group(1) + match.group(3)
        fraction_ns = int((match.group(2) + "000000000")[:9])
    try:
        when = datetime.fromisoformat(value)
    except ValueError:
        raise UsageError(
            f"{flag} {text!r}: expected seconds from the log's start (12.5) or an ISO 8601 time "
            "(2025-04-08T14:34:30Z; without an offset it is UTC)"
        ) from None
    if when.tzinfo is None:
        when = when.replace(tzinfo=UTC)
    delta = when - _EPOCH
    whole_s = delta.days * 86_400 + delta.seconds
    return TimeBound(flag, text, epoch_ns=whole_s * 1_000_000_000 + fraction_ns)


@dataclass(frozen=True)
class Selection:
    """What part of a log to use. Empty ``sensors``: all of them; None bounds: no limit.

    ``sensors`` holds shell-style patterns (``fnmatch``, case-sensitive): a sensor is used when an
    including pattern matches it (or there is none) and no excluding one (``!`` first) does.
    """

    sensors: tuple[str, ...] = ()
    start: TimeBound | None = None
    end: TimeBound | None = None

    @classmethod
    def parse(cls, sensors: Sequence[str], start: str | None, end: str | None) -> Selection:
        """The selection from the command line; :class:`UsageError` before any log is read."""
        for pattern in sensors:
            if not pattern.removeprefix(EXCLUDE).strip():
                raise UsageError(f"--sensors {pattern!r}: an empty pattern matches no sensor")
        lo = parse_time(start, "--start") if start is not None else None
        hi = parse_time(end, "--end") if end is not None else None
        selection = cls(tuple(sensors), lo, hi)
        if lo is not None and hi is not None:
            # same kind: the order is known before reading; mixed: once the log's start is
            if lo.offset_ns is not None and hi.offset_ns is not None:
                selection.check_order(lo.offset_ns, hi.offset_ns)
            if lo.epoch_ns is not None and hi.epoch_ns is not None:
                selection.check_order(lo.epoch_ns, hi.epoch_ns)
        return selection

    def __bool__(self) -> bool:
        return bool(self.sensors) or self.start is not None or self.end is not None

    def check_order(self, start_ns: int, end_ns: int) -> None:
        if start_ns >= end_ns:
            assert self.start is not None and self.end is not None
            raise UsageError(
                f"--start {self.start.text} is not before --end {self.end.text}: the window "
                "would be empty"
            )


@dataclass(frozen=True)
class Selected:
    """A selected log, the notes for the user, and what was chosen (for ``inspect``).

    ``start_ns``/``end_ns``: the window as stamps (None: unbounded); ``sensors_before``: how
    many sensors the log had before selection.
    """

    log: RangeLog
    notes: tuple[str, ...] = ()
    start_ns: int | None = None
    end_ns: int | None = None
    sensors_before: int = 0


def apply_selection(
    log: RangeLog,
    selection: Selection,
    robot: RobotDescription | None,
    need_readings: bool = True,
) -> Selected:
    """``log`` cut to ``selection``, CSV columns the robot lacks left out (with a note).

    Order: sensor patterns (on every name the log has), then columns that are no range sensor,
    then the window. ``need_readings``: a window holding no range reading is an error (build,
    evaluate, inspect); calibrate, which compares poses, passes False.
    """
    before = len(log.sensor_names)
    if selection.sensors:
        log = select_sensors(log, selection.sensors)
    log, notes = ignore_other_columns(log, robot)
    problem = stamp_problem(log)
    if problem is not None:
        notes = (*notes, f"{log.source}: {problem}")
    start_ns = end_ns = None
    if selection.start is not None or selection.end is not None:
        if problem is not None:
            asked = " ".join(f"{b.flag} {b.text}" for b in (selection.start, selection.end) if b)
            raise InputFileError(log.source, f"{asked} cannot be honoured: {problem}")
        origin = _log_span(log)[0]
        if selection.start is not None:
            start_ns = selection.start.stamp_ns(log, origin)
        if selection.end is not None:
            end_ns = selection.end.stamp_ns(log, origin)
        if start_ns is not None and end_ns is not None:
            selection.check_order(start_ns, end_ns)
        asked = " ".join(f"{b.flag} {b.text}" for b in (selection.start, selection.end) if b)
        log = select_window(log, start_ns, end_ns, need_readings, asked)
    return Selected(log, notes, start_ns, end_ns, before)


# ---------------------------------------------------------------------------------- sensors


def select_sensors(log: RangeLog, patterns: Sequence[str]) -> RangeLog:
    """The log with the sensors ``patterns`` choose (see :class:`Selection`).

    Raises :class:`UsageError`, listing the log's sensors, when a pattern matches none of them
    or the patterns leave no sensor.
    """
    names = log.sensor_names
    include = [p for p in patterns if not p.startswith(EXCLUDE)]
    exclude = [p.removeprefix(EXCLUDE) for p in patterns if p.startswith(EXCLUDE)]
    unmatched = [
        p for p in patterns if not any(fnmatchcase(n, p.removeprefix(EXCLUDE)) for n in names)
    ]
    if unmatched:
        raise UsageError(
            f"--sensors {', '.join(repr(p) for p in unmatched)} "
            f"match{'es' if len(unmatched) == 1 else ''} no sensor of {log.source} "
            f"(it has {names_text(names) or 'none'})"
        )
    keep = [
        n
        for n in names
        if (not include or any(fnmatchcase(n, p) for p in include))
        and not any(fnmatchcase(n, p) for p in exclude)
    ]
    if not keep:
        raise UsageError(
            f"--sensors {' '.join(repr(p) for p in patterns)} leave no sensor of {log.source} "
            f"(it has {names_text(names)})"
        )
    return keep_sensors(log, keep)


def keep_sensors(log: RangeLog, keep: Sequence[str]) -> RangeLog:
    """The log as if it had held only the sensors named in ``keep`` (kept in the log's order).

    ``readings.sensor`` is re-indexed into the new ``sensor_names``; the log's own sensor
    descriptions are kept for the names kept.
    """
    wanted = set(keep)
    old = log.sensor_names
    new_index = np.full(len(old), -1, dtype=np.int32)
    kept = [i for i, n in enumerate(old) if n in wanted]
    new_index[kept] = np.arange(len(kept), dtype=np.int32)
    r = log.readings
    mapped = new_index[r.sensor]
    rows = mapped >= 0
    readings = RangeReadings(r.stamp_ns[rows], mapped[rows], r.range_m[rows])
    stream = None if log.stream is None else log.stream.with_sensors(new_index)
    sensors = None
    if log.sensors is not None:
        sensors = tuple(s for s in log.sensors if s.name in wanted)
    return dataclasses.replace(
        log,
        readings=readings,
        sensor_names=tuple(old[i] for i in kept),
        sensors=sensors,
        stream=stream,
    )


def ignore_other_columns(
    log: RangeLog, robot: RobotDescription | None
) -> tuple[RangeLog, tuple[str, ...]]:
    """Leave out the columns of a column log (CSV) that name no sensor of ``robot`` or the log.

    Such a column is some other measurement (a battery voltage), not a range sensor. Returns the
    log and one note naming them; logs of other formats (whose sensors are sensors), or with no
    robot to judge by, come back unchanged.
    """
    if not log.names_are_columns or robot is None:
        return log, ()
    described = {s.name for s in log.sensors or ()} | set(robot.names())
    other = [n for n in log.sensor_names if n not in described]
    if not other:
        return log, ()
    if len(other) == len(log.sensor_names):
        raise InputFileError(
            log.source,
            f"no column is a range sensor of robot '{robot.name}' (columns "
            f"{names_text(other)}; the robot has {names_text(robot.names())}): give --robot",
        )
    if len(other) == 1:
        what = f"column '{other[0]}' is not a range sensor"
    else:
        shown = ", ".join(f"'{n}'" for n in other[:5])
        more = f" and {len(other) - 5} more" if len(other) > 5 else ""
        what = f"columns {shown}{more} are not range sensors"
    note = f"{log.source}: {what} of robot '{robot.name}'; ignored"
    return keep_sensors(log, [n for n in log.sensor_names if n in described]), (note,)


def names_text(names: Sequence[str], limit: int = 12) -> str:
    """Sensor names for people, numbered runs shortened: ``laser_0..laser_179, sonar0``.

    A run is consecutive numbers after the same prefix; more than ``limit`` groups end in
    ``and N more``.
    """
    groups: list[list[str]] = []
    last: tuple[str, int] | None = None
    for name in names:
        match = _NUMBERED.match(name)
        key = (match.group(1), int(match.group(2))) if match else None
        if key is not None and last is not None and key == (last[0], last[1] + 1):
            groups[-1].append(name)
        else:
            groups.append([name])
        last = key
    parts: list[str] = []
    for group in groups:
        if len(group) >= 3:
            parts.append(f"{group[0]}..{group[-1]}")
        else:
            parts.extend(group)
    if len(parts) > limit:
        return ", ".join(parts[:limit]) + f" and {len(parts) - limit} more"
    return ", ".join(parts)


# ------------------------------------------------------------------------------------- time


def _log_span(log: RangeLog) -> tuple[int, int]:
    """First and last stamp of the poses and readings together (ns); (0, 0) for an empty log."""
    ends = [
        int(t[i]) for t in (log.poses.stamp_ns, log.readings.stamp_ns) if len(t) for i in (0, -1)
    ]
    return (min(ends), max(ends)) if ends else (0, 0)


def select_window(
    log: RangeLog,
    start_ns: int | None,
    end_ns: int | None,
    need_readings: bool = True,
    asked: str = "",
) -> RangeLog:
    """The readings from ``start_ns`` up to (not including) ``end_ns``; None: no limit.

    The pose tracks (odometry and truth) keep their poses in the window and the last one at or
    before its start and the first one at or after its end, so that interpolation at the edges
    works as in the whole log. Raises :class:`UsageError` naming the log's time span when
    ``need_readings`` and no reading is left (``asked``: the flags as given, for that message).
    """
    if log.stream is not None:  # callers hold a log they cut in time (ReadOptions.stream)
        raise UsageError(f"{log.source}: a time window needs the log's readings held")
    r = log.readings
    rows = np.ones(len(r), dtype=bool)
    if start_ns is not None:
        rows &= r.stamp_ns >= start_ns
    if end_ns is not None:
        rows &= r.stamp_ns < end_ns
    if need_readings and not rows.any():
        lo = _stamp_text(start_ns) if start_ns is not None else "the start"
        hi = _stamp_text(end_ns) if end_ns is not None else "the end"
        raise UsageError(
            f"{log.source}: no range readings from {lo} to {hi}"
            f"{f' ({asked})' if asked else ''}; the log spans "
            f"{span_text(*_log_span(log))}"
        )
    readings = RangeReadings(r.stamp_ns[rows], r.sensor[rows], r.range_m[rows])
    truth = None if log.truth is None else _bracket(log.truth, start_ns, end_ns)
    return dataclasses.replace(
        log, readings=readings, poses=_bracket(log.poses, start_ns, end_ns), truth=truth
    )


def _bracket(track: PoseTrack, start_ns: int | None, end_ns: int | None) -> PoseTrack:
    """The poses within [start, end] and the nearest one outside each end."""
    n = len(track)
    if n == 0:
        return track
    t = track.stamp_ns
    first = 0 if start_ns is None else max(int(np.searchsorted(t, start_ns, "right")) - 1, 0)
    last = n - 1 if end_ns is None else min(int(np.searchsorted(t, end_ns, "left")), n - 1)
    part = slice(first, max(first, last) + 1)
    return PoseTrack(t[part], track.x_m[part], track.y_m[part], track.theta_rad[part])
