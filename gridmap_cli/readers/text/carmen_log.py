"""Reader for CARMEN logs (``.log``, ``.clf``): the classic 2D SLAM data sets.

One message per line: a name, its fields, then ``ipc_timestamp hostname logger_timestamp``
(``schemas/carmen-log.md`` lists the layouts, the quirks of the published *corrected* logs and
what we do about each). We read ``ODOM x y theta tv rv accel``, ``FLASER``/``RLASER
num_readings ranges... x y theta odom_x odom_y odom_theta``, ``ROBOTLASER1``/``2`` and
``RAWLASER1``..``4`` (laser configuration, ranges, remissions; ROBOTLASER adds poses and
velocities), ``TRUEPOS true_x true_y true_theta odom_x odom_y odom_theta`` and the ``PARAM`` lines
that describe the lasers; ``SYNC``, ``NEFF`` and any other message are skipped.

The odometry is recovered by :mod:`gridmap_cli.readers.text.carmen_tracks`: in a corrected log the
``ODOM`` lines restart from each scan's corrected pose, so the robot's own odometry is the chain
of the increments between consecutive ``ODOM`` lines. Laser beams become ray sensors
``<laser>_<i>`` (``frontlaser``, ``rearlaser``, ``laser3``, ``laser4``) mounted as the PARAM lines
say, so no ``--robot`` is needed.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import InputFileError
from gridmap_cli.limits import MAX_LASER_SAMPLES, numbered_lines, too_many_beams
from gridmap_cli.readers.text.carmen_layout import layout_from_params
from gridmap_cli.readers.text.carmen_tracks import Event, build_tracks
from gridmap_cli.readers.text.csv_log import seconds_to_ns
from gridmap_cli.readers.text.source import parse_text
from gridmap_cli.records import RangeLog, RangeReadings
from gridmap_cli.robot import BeamBook, RangeSensor

EXTENSIONS = (".clf",)
#: ``.log`` is CARMEN's usual extension but everyone's: the registry sniffs such files first.
WEAK_EXTENSIONS = (".log",)

#: CARMEN's readlog gives FLASER/RLASER messages this maximum range (metres) when no PARAM does.
DEFAULT_MAX_RANGE_M = 80.0

#: A laser's largest reading, repeated at least this often, is its "no echo" value (some logs
#: write a fixed 50 m below the laser's stated maximum).
NO_ECHO_MIN_COUNT = 10

#: Laser number (CARMEN's: 1 front, 2 rear) -> sensor name prefix and the PARAM words for it.
LASER_NAMES = {1: "frontlaser", 2: "rearlaser", 3: "laser3", 4: "laser4"}
_PARAM_WORD = {1: "front", 2: "rear"}

_TRAILER = 3  # ipc_timestamp hostname logger_timestamp
_NAME = re.compile(r"^[A-Z][A-Z0-9_]*$")
_NUMBERED = re.compile(r"^(ROBOTLASER|RAWLASER)([1-4])$")
_SNIFF = {"PARAM", "SYNC", "ODOM", "FLASER", "RLASER", "TRUEPOS", "ROBOTLASER1", "RAWLASER1"}

Pose = tuple[float, float, float]


def sniff(head: bytes) -> bool:
    """True if the first bytes look like a CARMEN log: its header comment or a known message."""
    text = head.decode("latin-1")
    for raw in text.splitlines():
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            if "CARMEN" in line or "message formats defined" in line:
                return True
            continue
        return line.split()[0] in _SNIFF
    return False


@dataclass
class Scan:
    """One laser scan as read: ranges in metres (NaN: no reading), beam layout, pose if any."""

    line: int
    message: str
    laser: int
    stamp_ns: int
    ranges: npt.NDArray[np.float64]
    pose: Pose | None  # the robot pose fields (odom_x.. / robot_pose); None for RAWLASER
    start_rad: float | None = None  # None: FLASER/RLASER, layout from PARAM or beam count
    step_rad: float | None = None
    max_range_m: float | None = None


@dataclass
class _Laser:
    number: int
    sources: dict[str, int] = field(default_factory=dict)  # message -> scans
    layout: tuple[int, float, float] | None = None  # the first scan's count, start_rad, step_rad
    book: BeamBook | None = None  # the beam directions of its scans (the first scan's first)
    layouts: int = 0  # distinct layouts among its scans
    max_range_m: float = DEFAULT_MAX_RANGE_M
    max_from: str = "CARMEN's default"
    params_read: str = ""  # how the fov/resolution PARAM lines were read


def read_carmen_log(source: str | Path | TextIO, name: str | None = None) -> RangeLog:
    """Read a CARMEN log from a path or an open text handle (``name`` names a handle).

    Raises :class:`InputFileError` with ``path:line`` for anything malformed.
    """
    # CARMEN writes ASCII; latin-1 reads any byte so that errors can name the line
    return parse_text(source, name, lambda handle, path: _Parser(path).parse(handle), "latin-1")


class _Parser:
    def __init__(self, path: str) -> None:
        self.path = path
        self.params: dict[str, tuple[str, int]] = {}  # name -> (value, line)
        self.events: list[Event] = []
        self.scans: list[Scan] = []
        self.skipped: dict[str, int] = {}
        self.duplicates: list[str] = []

    def error(self, line: int, detail: str) -> InputFileError:
        return InputFileError(self.path, detail, line)

    # ------------------------------------------------------------------------------ fields

    def number(self, line: int, message: str, token: str, what: str) -> float:
        try:
            value = float(token)
        except ValueError:
            raise self.error(line, f"{message}: {what}: not a number: {token!r}") from None
        if not math.isfinite(value):
            raise self.error(line, f"{message}: {what}: not a finite number: {token!r}")
        return value

    def count(self, line: int, message: str, token: str, what: str) -> int:
        try:
            value = int(token)
        except ValueError:
            raise self.error(line, f"{message}: {what}: not a whole number: {token!r}") from None
        if value < 0:
            raise self.error(line, f"{message}: {what}: negative: {token!r}")
        return value

    def pose(self, line: int, message: str, tokens: list[str], what: str) -> Pose:
        names = ("x", "y", "theta")
        x, y, th = (
            self.number(line, message, t, f"{what} {n}") for t, n in zip(tokens, names, strict=True)
        )
        return x, y, th

    def stamp(self, line: int, message: str, tokens: list[str]) -> int:
        """The message's own time: ``ipc_timestamp``, third field from the end."""
        token = tokens[-_TRAILER]
        try:
            return seconds_to_ns(token)
        except ValueError as exc:
            raise self.error(line, f"{message}: ipc_timestamp: {exc}") from None

    def ranges(self, line: int, message: str, tokens: list[str]) -> npt.NDArray[np.float64]:
        try:
            values = np.asarray(tokens, dtype=np.float64)
        except ValueError:
            for token in tokens:
                self.number(line, message, token, "range")  # raises for the first bad one
            raise  # pragma: no cover (float() and numpy agree on what a number is)
        if (values < 0).any():
            bad = tokens[int(np.argmax(values < 0))]
            raise self.error(line, f"{message}: negative range {bad}")
        values[np.isnan(values) | (values == 0.0)] = np.nan  # 0: no reading, as SICK writes it
        return values

    def fields(self, line: int, message: str, tokens: list[str], expected: int, what: str) -> None:
        if len(tokens) != expected:
            hint = " (truncated line?)" if len(tokens) < expected else ""
            raise self.error(
                line,
                f"{message}: expected {expected} fields ({what} ipc_timestamp hostname "
                f"logger_timestamp), found {len(tokens)}{hint}",
            )

    # ------------------------------------------------------------------------------ lines

    def parse(self, handle: TextIO) -> RangeLog:
        number = 0
        for number, raw in numbered_lines(handle, self.path):
            tokens = raw.split()
            if not tokens or tokens[0].startswith("#"):
                continue
            message = tokens[0].lstrip("\ufeff")
            if not _NAME.match(message):
                raise self.error(number, f"not a CARMEN message line: {raw.strip()[:40]!r}")
            self.message(number, message, tokens)
        if not self.events and not self.params:
            raise InputFileError(self.path, "no CARMEN messages in the log (empty file?)")
        return self.finish(number)

    def message(self, line: int, message: str, tokens: list[str]) -> None:
        numbered = _NUMBERED.match(message)
        if message == "ODOM":
            self.fields(line, message, tokens, 10, "x y theta tv rv accel")
            pose = self.pose(line, message, tokens[1:4], "pose")
            self.events.append(Event("odom", line, self.stamp(line, message, tokens), pose))
        elif message in ("FLASER", "RLASER"):
            self.old_laser(line, message, tokens)
        elif message == "TRUEPOS":
            self.fields(
                line, message, tokens, 10, "true_x true_y true_theta odom_x odom_y odom_theta"
            )
            pose = self.pose(line, message, tokens[1:4], "true pose")
            self.events.append(Event("truepos", line, self.stamp(line, message, tokens), pose))
        elif numbered is not None:
            self.new_laser(line, message, tokens, numbered.group(1) == "ROBOTLASER")
        elif message == "PARAM":
            if len(tokens) < 3:
                raise self.error(line, "PARAM: expected a name and a value")
            self.params[tokens[1]] = (tokens[2], line)
        else:  # SYNC, NEFF, and what CARMEN modules we do not map log
            self.skipped[message] = self.skipped.get(message, 0) + 1

    def add_scan(self, scan: Scan) -> None:
        self.events.append(Event("scan", scan.line, scan.stamp_ns, scan.pose, len(self.scans)))
        self.scans.append(scan)

    def old_laser(self, line: int, message: str, tokens: list[str]) -> None:
        """``FLASER``/``RLASER num_readings ranges... x y theta odom_x odom_y odom_theta``."""
        if len(tokens) < 2:
            raise self.error(line, f"{message}: expected num_readings after the message name")
        n = self.count(line, message, tokens[1], "num_readings")
        if n > MAX_LASER_SAMPLES:
            raise too_many_beams(self.path, n, line, f"{message}: ")
        expected = n + 2 + 6 + _TRAILER
        if len(tokens) != expected:
            raise self.error(
                line,
                f"{message}: num_readings {n} means {expected} fields (ranges, laser and robot "
                f"pose, ipc_timestamp hostname logger_timestamp), found {len(tokens)}",
            )
        ranges = self.ranges(line, message, tokens[2 : 2 + n])
        self.pose(line, message, tokens[2 + n : 5 + n], "laser pose")
        robot = self.pose(line, message, tokens[5 + n : 8 + n], "robot pose")
        laser = 1 if message == "FLASER" else 2
        self.add_scan(Scan(line, message, laser, self.stamp(line, message, tokens), ranges, robot))

    def new_laser(self, line: int, message: str, tokens: list[str], with_pose: bool) -> None:
        """``ROBOTLASER<k>``/``RAWLASER<k>``: laser configuration, ranges, remissions[, poses].

        The configuration is ``laser_type start_angle fov angular_resolution maximum_range
        accuracy remission_mode``; CARMEN versions before remission_mode wrote six fields, so
        both are accepted when the counts fit.
        """
        tail = (6 + 5 if with_pose else 0) + _TRAILER  # poses, tv rv safety dists turn_axis
        layout: tuple[int, int, int] | None = None
        for n_config in (7, 6):
            if len(tokens) <= n_config + 1:
                continue
            try:
                n = int(tokens[n_config + 1])
                n_rem = int(tokens[n_config + 2 + n]) if n >= 0 else -1
            except (ValueError, IndexError):
                continue
            if n >= 0 and n_rem >= 0 and len(tokens) == n_config + 3 + n + n_rem + tail:
                layout = (n_config, n, n_rem)
                break
        if layout is None:
            if len(tokens) < 9:
                raise self.error(line, f"{message}: expected the laser configuration and readings")
            n = self.count(line, message, tokens[8], "num_readings")
            if len(tokens) <= 9 + n:
                raise self.error(
                    line, f"{message}: num_readings {n} but only {len(tokens) - 9} fields follow"
                )
            n_rem = self.count(line, message, tokens[9 + n], "num_remissions")
            raise self.error(
                line,
                f"{message}: num_readings {n} and num_remissions {n_rem} mean "
                f"{10 + n + n_rem + tail} fields, found {len(tokens)}",
            )
        n_config, n, _ = layout
        if n > MAX_LASER_SAMPLES:
            raise too_many_beams(self.path, n, line, f"{message}: ")
        what = ("laser_type", "start_angle", "fov", "angular_resolution", "maximum_range")
        config = [self.number(line, message, t, w) for t, w in zip(tokens[1:6], what, strict=True)]
        ranges = self.ranges(line, message, tokens[n_config + 2 : n_config + 2 + n])
        robot: Pose | None = None
        if with_pose:
            at = len(tokens) - tail
            self.pose(line, message, tokens[at : at + 3], "laser pose")
            robot = self.pose(line, message, tokens[at + 3 : at + 6], "robot pose")
        laser = int(message[-1])
        stamp = self.stamp(line, message, tokens)
        max_range = config[4] if config[4] > 0 else None
        scan = Scan(line, message, laser, stamp, ranges, robot, config[1], config[3], max_range)
        self.add_scan(scan)

    # ------------------------------------------------------------------------------ result

    def param(self, name: str, default: float | None = None) -> float | None:
        if name not in self.params:
            return default
        value, line = self.params[name]
        return self.number(line, "PARAM", value, name)

    def finish(self, last_line: int) -> RangeLog:
        lasers = self.choose_lasers(last_line)
        used = {id(s) for s in self.scans if s.laser in lasers and _source(s) == lasers[s.laser]}
        kept = [e for e in self.events if e.kind != "scan" or id(self.scans[e.scan]) in used]
        beams: dict[int, npt.NDArray[np.int64]] = {}
        layouts = {n: self.laser_layout(n, msg, beams) for n, msg in lasers.items()}
        sensors, names, offsets = self.sensors(layouts)
        tracks = build_tracks(self.path, kept, last_line)
        stamps, index, ranges = [], [], []
        no_echo = dict.fromkeys(layouts, 0)
        for event, stamp_ns in zip(kept, tracks.event_stamps_ns, strict=True):
            if event.kind != "scan":
                continue
            scan = self.scans[event.scan]
            # at or beyond the maximum: SICK's error codes (81.83, 81.91) or a clipped 50 m: no
            # echo, which the ray model clears only up to its cap (--no-echo-free)
            beyond = scan.ranges >= layouts[scan.laser].max_range_m
            no_echo[scan.laser] += int(np.count_nonzero(beyond))
            present = ~np.isnan(scan.ranges)
            stamps.append(np.full(int(present.sum()), stamp_ns, dtype=np.int64))
            index.append(offsets[scan.laser] + beams[id(scan)][present])
            ranges.append(np.where(beyond, np.inf, scan.ranges)[present])
        readings = RangeReadings(
            stamp_ns=np.concatenate(stamps),
            sensor=np.concatenate(index).astype(np.int32),
            range_m=np.concatenate(ranges),
        )
        metadata = dict(tracks.notes)
        for number, laser in sorted(layouts.items()):
            assert laser.layout is not None
            count, start, step = laser.layout
            varied = ""
            if laser.layouts > 1 and laser.book is not None:
                varied = f" (and {laser.layouts - 1} other layouts: {len(laser.book)} directions)"
            metadata[LASER_NAMES[number]] = (
                f"{lasers[number]}, {count} beams from {math.degrees(start):g} deg every "
                f"{math.degrees(step):g} deg{varied}, max range {laser.max_range_m:g} m "
                f"({laser.max_from}); {no_echo[number]} readings at or beyond it: no echo"
                + (f"; PARAM {laser.params_read}" if laser.params_read else "")
            )
        skipped = [f"{m} {c}" for m, c in sorted(self.skipped.items())]
        skipped += self.duplicates
        if skipped:
            metadata["skipped"] = ", ".join(skipped)
        return RangeLog(
            source=self.path,
            poses=tracks.odometry,
            readings=readings,
            sensor_names=tuple(names),
            sensors=tuple(sensors),
            truth=tracks.truth,
            metadata=metadata,
            odometry_missing=tracks.odometry_missing,
            moved_stamps=tracks.moved,
        )

    def choose_lasers(self, last_line: int) -> dict[int, str]:
        """Per laser, the message kind to map: the one with poses when a laser has both.

        CARMEN's logger writes a laser as RAWLASER<k> (no pose) and again as ROBOTLASER<k> or
        FLASER/RLASER (with the robot pose): the same scans, which must be mapped once.
        """
        if not self.scans:
            raise self.error(
                last_line,
                "no laser lines (FLASER, RLASER, ROBOTLASER1-4, RAWLASER1-4) in the log: "
                "nothing to map",
            )
        by_laser: dict[int, dict[str, int]] = {}
        for scan in self.scans:
            kinds = by_laser.setdefault(scan.laser, {})
            kinds[_source(scan)] = kinds.get(_source(scan), 0) + 1
        chosen: dict[int, str] = {}
        for number, kinds in sorted(by_laser.items()):
            order = [k for k in ("ROBOTLASER", "FLASER", "RLASER", "RAWLASER") if k in kinds]
            chosen[number] = order[0]
            self.duplicates += [f"{k}{number if k in _NUMBERED_KINDS else ''} {kinds[k]} "
                                f"(same laser as {order[0]})" for k in order[1:]]  # fmt: skip
        return chosen

    def laser_layout(
        self, number: int, source: str, beams: dict[int, npt.NDArray[np.int64]]
    ) -> _Laser:
        """A laser's beams and maximum range, from its messages and the PARAM lines; each
        scan's beam sensors go into ``beams`` (by the scan's id)."""
        laser = _Laser(number)
        word = _PARAM_WORD.get(number)
        biggest = 0.0
        layouts: set[tuple[int, float, float]] = set()
        for scan in self.scans:
            if scan.laser != number or _source(scan) != source:
                continue
            n = len(scan.ranges)
            if scan.start_rad is None or scan.step_rad is None:
                fov = self.param(f"laser_{word}_laser_fov") if word else None
                res = self.param(f"laser_{word}_laser_resolution") if word else None
                read = layout_from_params(fov, res, n, _guess_step(n))
                start, step = read.start_rad, read.step_rad
                laser.params_read = read.read
            else:
                start, step = scan.start_rad, scan.step_rad
            if laser.layout is None or laser.book is None:
                laser.layout = (n, start, step)
                laser.book = BeamBook(start, step, n)
                if scan.max_range_m is not None:
                    laser.max_range_m, laser.max_from = scan.max_range_m, "maximum_range field"
            # each scan with its own layout (lasers interleave start angles, add a beam)
            beams[id(scan)] = laser.book.sensors(start, step, n)
            layouts.add((n, start, step))
            finite = scan.ranges[np.isfinite(scan.ranges)]
            if finite.size:
                biggest = max(biggest, float(finite.max()))
        laser.layouts = len(layouts)
        if source in ("FLASER", "RLASER") and word is not None:
            given = self.param(f"robot_{word}_laser_max")
            if given is not None and given > 0:
                laser.max_range_m, laser.max_from = given, f"PARAM robot_{word}_laser_max"
        # a no-echo value below the maximum would map as walls that far away
        if 0 < biggest < laser.max_range_m:
            hits = sum(
                int(np.count_nonzero(s.ranges == biggest))
                for s in self.scans
                if s.laser == number and _source(s) == source
            )
            if hits >= NO_ECHO_MIN_COUNT:
                laser.max_range_m = biggest
                laser.max_from = f"the no-echo value the log writes {hits} times"
        return laser

    def sensors(
        self, layouts: dict[int, _Laser]
    ) -> tuple[list[RangeSensor], list[str], dict[int, int]]:
        """Every laser's beams as ray sensors, mounted as the PARAM lines say."""
        sensors: list[RangeSensor] = []
        names: list[str] = []
        offsets: dict[int, int] = {}
        for number, laser in sorted(layouts.items()):
            assert laser.book is not None
            book = laser.book
            x, y, yaw = self.mounting(number)
            offsets[number] = len(sensors)
            yaws = yaw + book.start + book.local * book.step
            for i, beam_yaw in enumerate(yaws.tolist()):
                name = f"{LASER_NAMES[number]}_{i}"
                names.append(name)
                sensors.append(
                    RangeSensor(name, x, y, beam_yaw, 0.0, 0.0, laser.max_range_m, "laser")
                )
        return sensors, names, offsets

    def mounting(self, number: int) -> Pose:
        """Laser pose in the robot frame: the front one ``robot_frontlaser_offset`` ahead facing
        forward, the rear one ``robot_rearlaser_offset`` behind facing backward (as CARMEN's
        localize places them); lasers 3 and 4 have no PARAM: at the centre, facing forward."""
        if number == 1:
            x = self.param("robot_frontlaser_offset", 0.0) or 0.0
            y = self.param("robot_frontlaser_side_offset", 0.0) or 0.0
            yaw = self.param("robot_frontlaser_angular_offset", 0.0) or 0.0
            return x, y, yaw
        if number == 2:
            x = self.param("robot_rearlaser_offset", 0.0) or 0.0
            return -x, 0.0, math.pi
        return 0.0, 0.0, 0.0


_NUMBERED_KINDS = ("ROBOTLASER", "RAWLASER")


def _source(scan: Scan) -> str:
    """The message kind of a scan without its laser number (``ROBOTLASER``, ``FLASER``, ...)."""
    return scan.message.rstrip("1234") if scan.message[-1].isdigit() else scan.message


def _guess_step(count: int) -> float:
    """Beam spacing CARMEN's readlog assumes for a FLASER/RLASER of ``count`` beams (radians).

    180 or 181 beams: 1 degree; 360 or 361: 0.5; 400 or 401: 0.25; otherwise 180 degrees
    spread over the beams.
    """
    if count in (180, 181):
        return math.pi / 180.0
    if count in (360, 361):
        return math.pi / 360.0
    if count in (400, 401):
        return math.pi / 720.0
    return math.pi / (count - 1) if count > 1 else 0.0
