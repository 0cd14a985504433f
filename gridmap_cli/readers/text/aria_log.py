"""Reader for ARIA "LaserOdometryLog" text logs (``.2d``), versions 1 to 4, plus sonar.

ArLaserLogger / ArSickLogger write these, and Mapper3 and MobilePlanner read them
(``schemas/aria-log.md`` describes what we read). The file starts with ``LaserOdometryLog``;
every other line is a ``#`` comment or a ``tag: values`` line. Tags we do not know are ignored,
as ARIA's own documentation asks.

Header tags: ``version:``, ``sick<N>pose: X Y Th`` / ``scan<N>pose: X Y [Z] Th`` (laser mounting,
mm and degrees), ``sick<N>conf:`` / ``scan<N>conf: first_deg last_deg samples``,
``locationTypes:``, gridmap's laser range extension ``sick<N>maxRange: mm`` /
``sick<N>minRange: mm`` (or ``scan<N>...``; ARIA writes no laser range, so without them a laser
reaches :data:`LASER_MAX_RANGE_M` and its readings are taken as they are), and gridmap's sonar
extension ``sonarUnit: n X Y Th`` (as a ``.p`` file's SonarUnit) and ``sonarMaxRange: mm``.

Blocks start at ``time:`` (versions 1-2) or ``logTime:`` (3-4), seconds since the start of the log.
A block holds ``robot: X Y Th`` (encoder pose, mm mm deg), optionally ``robotGlobal:`` (corrected
pose) and ``robotRaw:``, then readings: ``sick<N>: r...`` (ranges in mm, old form), ``scan<N>: x y
x y ...`` (end points in mm in the robot frame; ``0 0`` marks an ignored reading) and
``sonar: r...`` (one range in mm per sonar unit). A block with a ``cairn:`` line is a goal
marker, not data.

Laser readings become one range sensor per beam (``laser<N>_<i>``, a ray); sonar readings use the
units from the header, or the robot description (``--robot``) when the header has none.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np

from gridmap_cli.errors import InputFileError
from gridmap_cli.limits import MAX_LASER_SAMPLES, numbered_lines
from gridmap_cli.readers.text.csv_log import seconds_to_ns
from gridmap_cli.readers.text.source import parse_text
from gridmap_cli.records import PoseTrack, RangeLog, RangeReadings
from gridmap_cli.robot import RangeSensor, laser_beams
from gridmap_cli.robot.aria_params import (
    DEFAULT_BEAM_WIDTH_DEG,
    DEFAULT_MIN_RANGE_M,
    DEFAULT_SONAR_MAX_RANGE_MM,
)

MAGIC = "LaserOdometryLog"

#: ARIA writes no laser maximum range in the log; without gridmap's ``sick<N>maxRange:`` line a
#: laser is taken to reach this far, and its readings are end points or ranges that hit.
LASER_MAX_RANGE_M = 32.0

#: The LaserOdometryLog versions ARIA has written, all of which this reader knows.
KNOWN_VERSIONS = ("1", "2", "3", "4")
_LASER_TAG = re.compile(r"^(sick|scan)(\d+)(pose|conf|id|name|maxrange|minrange)?$", re.IGNORECASE)


def sniff(head: bytes) -> bool:
    """True if the first bytes start an ARIA laser-odometry log."""
    return head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(MAGIC.encode())


@dataclass
class _Laser:
    number: int
    pose: tuple[float, float, float] | None = None  # x_m, y_m, yaw_rad
    conf: tuple[float, float, int] | None = None  # first_deg, last_deg, samples
    line: int = 0
    max_range_m: float | None = None  # gridmap's sick<N>maxRange:, None in ARIA's own logs
    min_range_m: float = 0.0  # gridmap's sick<N>minRange:
    range_line: int = 0  # where the later of the two range lines is, for errors


@dataclass
class _Block:
    line: int
    stamp_ns: int
    robot: tuple[float, float, float] | None = None
    global_pose: tuple[float, float, float] | None = None
    lasers: dict[int, tuple[int, str, list[float]]] = field(default_factory=dict)
    sonar: tuple[int, list[float]] | None = None
    goal: bool = False


def read_aria_log(source: str | Path | TextIO, name: str | None = None) -> RangeLog:
    """Read a ``.2d`` log from a path or an open text handle (``name`` names a handle).

    Raises :class:`InputFileError` with ``path:line`` for anything malformed.
    """
    # ARIA writes ASCII; latin-1 reads any byte so that errors can name the line
    return parse_text(source, name, lambda handle, path: _Parser(path).parse(handle), "latin-1")


class _Parser:
    def __init__(self, path: str) -> None:
        self.path = path
        self.version: str | None = None
        self.lasers: dict[int, _Laser] = {}
        self.sonar_units: dict[int, tuple[float, float, float, int]] = {}
        self.sonar_max_m = DEFAULT_SONAR_MAX_RANGE_MM / 1000.0  # as the Pioneer presets
        self.blocks: list[_Block] = []
        self.metadata: dict[str, str] = {}

    def error(self, line: int, detail: str) -> InputFileError:
        return InputFileError(self.path, detail, line)

    def numbers(self, line: int, tag: str, values: str, count: int | None = None) -> list[float]:
        try:  # the common case in one go; the loop below finds and words a bad token
            out = list(map(float, values.split()))
        except ValueError:
            pass
        else:
            if all(map(math.isfinite, out)) and (count is None or len(out) >= count):
                return out
        out = []
        for token in values.split():
            try:
                value = float(token)
            except ValueError:
                raise self.error(line, f"{tag}: not a number: {token!r}") from None
            if not math.isfinite(value):
                raise self.error(line, f"{tag}: not a finite number: {token!r}")
            out.append(value)
        if count is not None and len(out) < count:
            raise self.error(line, f"{tag}: expected {count} numbers, found {len(out)}")
        return out

    def pose(self, line: int, tag: str, values: str) -> tuple[float, float, float]:
        x, y, th = self.numbers(line, tag, values, 3)[:3]
        return x / 1000.0, y / 1000.0, math.radians(th)

    def parse(self, handle: TextIO) -> RangeLog:
        lines = numbered_lines(handle, self.path)
        number, first = 1, ""
        for number, raw in lines:  # noqa: B007 (number is used after the loop)
            first = raw.strip().lstrip("\ufeff")
            if first:
                break
        if first != MAGIC:
            raise self.error(number, f"not an ARIA laser log: expected '{MAGIC}' first")
        block: _Block | None = None
        for number, raw in lines:
            text = raw.strip()
            if not text:
                continue
            if text.startswith("#"):
                key, sep, value = text[1:].partition(":")
                if block is None and sep and key.strip() and " " not in key.strip():
                    self.metadata[key.strip()] = value.strip()
                continue
            tag, sep, values = text.partition(":")
            if not sep:
                raise self.error(number, f"expected 'tag: values', found {text[:40]!r}")
            tag = tag.strip()
            low = tag.lower()
            if low in ("time", "logtime"):
                block = self.start_block(number, tag, values)
                continue
            if block is None:
                self.header(number, tag, low, values)
                continue
            self.block_line(block, number, tag, low, values)
        return self.finish(number)

    def header(self, line: int, tag: str, low: str, values: str) -> None:
        if low == "version":
            self.version = values.strip()
            if self.version not in KNOWN_VERSIONS:
                raise self.error(
                    line,
                    f"version {self.version!r}: gridmap reads LaserOdometryLog versions "
                    f"{', '.join(KNOWN_VERSIONS)} (a later ARIA may lay the lines out otherwise)",
                )
            self.metadata["version"] = self.version
        elif low == "sonarunit":
            n, x, y, th = self.numbers(line, tag, values, 4)[:4]
            if n != int(n) or n < 0:
                raise self.error(line, f"{tag}: unit number must be a whole number, got {n:g}")
            if int(n) in self.sonar_units:
                raise self.error(line, f"{tag}: unit {int(n)} declared twice")
            self.sonar_units[int(n)] = (x / 1000.0, y / 1000.0, math.radians(th), line)
        elif low == "sonarmaxrange":
            (mm,) = self.numbers(line, tag, values, 1)[:1]
            if mm <= 0:
                raise self.error(line, f"{tag}: must be positive, got {mm:g}")
            self.sonar_max_m = mm / 1000.0
        elif low == "locationtypes":
            self.metadata["locationTypes"] = values.strip()
        else:
            match = _LASER_TAG.match(tag)
            if match and match.group(3):
                laser = self.lasers.setdefault(int(match.group(2)), _Laser(int(match.group(2))))
                kind = match.group(3).lower()
                if kind == "pose":
                    nums = self.numbers(line, tag, values, 3)
                    # scan<N>pose has X Y Z Th since version 4; sick<N>pose has X Y Th
                    x, y, th = (nums[0], nums[1], nums[-1]) if len(nums) >= 4 else nums[:3]
                    laser.pose = (x / 1000.0, y / 1000.0, math.radians(th))
                elif kind == "conf":
                    first, last, samples = self.numbers(line, tag, values, 3)[:3]
                    if samples != int(samples) or samples < 1:
                        raise self.error(line, f"{tag}: samples must be a whole number >= 1")
                    if samples > MAX_LASER_SAMPLES:
                        raise self.error(
                            line,
                            f"{tag}: {samples:.0f} samples, above gridmap's limit of "
                            f"{MAX_LASER_SAMPLES:,} beams per laser (MAX_LASER_SAMPLES)",
                        )
                    laser.conf = (first, last, int(samples))
                    laser.line = line
                elif kind == "maxrange":
                    (mm,) = self.numbers(line, tag, values, 1)[:1]
                    if mm <= 0:
                        raise self.error(line, f"{tag}: must be positive, got {mm:g}")
                    laser.max_range_m, laser.range_line = mm / 1000.0, line
                elif kind == "minrange":
                    (mm,) = self.numbers(line, tag, values, 1)[:1]
                    if mm < 0:
                        raise self.error(line, f"{tag}: must not be negative, got {mm:g}")
                    laser.min_range_m, laser.range_line = mm / 1000.0, line

    def start_block(self, line: int, tag: str, values: str) -> _Block:
        try:
            stamp = seconds_to_ns(values.strip())
        except ValueError as exc:
            raise self.error(line, f"{tag}: {exc}") from None
        block = _Block(line=line, stamp_ns=stamp)
        self.blocks.append(block)
        return block

    def block_line(self, block: _Block, line: int, tag: str, low: str, values: str) -> None:
        if low == "robot":
            block.robot = self.pose(line, tag, values)
        elif low == "robotglobal":
            block.global_pose = self.pose(line, tag, values)
        elif low == "cairn":
            block.goal = True
        elif low == "sonar":
            block.sonar = (line, self.numbers(line, tag, values))
        else:
            match = _LASER_TAG.match(tag)
            if match and match.group(3) is None:
                form = match.group(1).lower()
                number = int(match.group(2))
                block.lasers[number] = (line, form, self.numbers(line, tag, values))

    def finish(self, last_line: int) -> RangeLog:
        data = [b for b in self.blocks if not b.goal]
        if not data:
            raise self.error(last_line, "no reading blocks (time: or logTime: lines) in the log")
        for prev, block in itertools.pairwise(data):
            if block.stamp_ns <= prev.stamp_ns:
                what = "repeats" if block.stamp_ns == prev.stamp_ns else "goes backwards"
                raise self.error(
                    block.line,
                    f"time {what}: {block.stamp_ns / 1e9:.9g} s after {prev.stamp_ns / 1e9:.9g} s "
                    f"(block at line {prev.line}); blocks must be in increasing time",
                )
        for block in data:
            if block.robot is None:
                raise self.error(block.line, "block has no 'robot:' pose")
        sensors, names, offsets = self.sensors(data)
        readings = self.readings(data, names, offsets)
        stamps = np.asarray([b.stamp_ns for b in data], dtype=np.int64)
        poses = PoseTrack.from_rows(stamps, [b.robot for b in data if b.robot is not None])
        truth = None
        if all(b.global_pose is not None for b in data):
            truth = PoseTrack.from_rows(
                stamps, [b.global_pose for b in data if b.global_pose is not None]
            )
        return RangeLog(
            source=self.path,
            poses=poses,
            readings=readings,
            sensor_names=tuple(names),
            sensors=tuple(s for s in sensors if s is not None),
            truth=truth,
            metadata=self.metadata,
        )

    def sensors(
        self, data: list[_Block]
    ) -> tuple[list[RangeSensor | None], list[str], dict[str, int]]:
        """Sensors in the order of a block's lines as gridmap writes them (and of the robot
        presets): the sonar units, then every laser's beams."""
        sensors: list[RangeSensor | None] = []
        names: list[str] = []
        offsets: dict[str, int] = {}
        if any(b.sonar is not None for b in data):
            offsets["sonar"] = len(sensors)
            if self.sonar_units:
                expected = list(range(len(self.sonar_units)))
                if sorted(self.sonar_units) != expected:
                    line = min(u[3] for u in self.sonar_units.values())
                    raise self.error(
                        line, f"sonarUnit numbers must be 0..{len(expected) - 1} without gaps"
                    )
                for n in expected:
                    x, y, th, _ = self.sonar_units[n]
                    names.append(f"sonar{n}")
                    sensors.append(
                        RangeSensor(
                            f"sonar{n}", x, y, th, math.radians(DEFAULT_BEAM_WIDTH_DEG),
                            DEFAULT_MIN_RANGE_M, self.sonar_max_m,
                        )
                    )  # fmt: skip
            else:
                # geometry comes from --robot, matched by these names
                count = max(len(b.sonar[1]) for b in data if b.sonar is not None)
                for n in range(count):
                    names.append(f"sonar{n}")
                    sensors.append(None)
        used = sorted({n for b in data for n in b.lasers})
        for number in used:
            laser = self.lasers.get(number)
            if laser is None or laser.conf is None:
                line = next(b.lasers[number][0] for b in data if number in b.lasers)
                raise self.error(line, f"laser {number} readings but no sick{number}conf: header")
            lx, ly, lth = laser.pose or (0.0, 0.0, 0.0)
            first, last, samples = laser.conf
            rmax = LASER_MAX_RANGE_M if laser.max_range_m is None else laser.max_range_m
            if laser.min_range_m >= rmax:
                raise self.error(
                    laser.range_line,
                    f"laser {number}: minimum range {laser.min_range_m * 1000.0:g} mm is not "
                    f"below the maximum range {rmax * 1000.0:g} mm",
                )
            offsets[f"laser{number}"] = len(sensors)
            beams = laser_beams(f"laser{number}", lx, ly, lth, first, last, samples,
                                laser.min_range_m, rmax)  # fmt: skip
            sensors += beams
            names += [beam.name for beam in beams]
        return sensors, names, offsets

    def readings(
        self, data: list[_Block], names: list[str], offsets: dict[str, int]
    ) -> RangeReadings:
        n_sonar = sum(1 for name in names if name.startswith("sonar"))
        if not any(block.lasers for block in data):
            return self.sonar_readings(data, n_sonar, offsets.get("sonar", 0))
        stamps: list[np.ndarray] = []
        index: list[np.ndarray] = []
        ranges: list[np.ndarray] = []
        for block in data:
            if block.sonar is not None:
                line, values = block.sonar
                if len(values) != n_sonar:
                    raise self.error(
                        line,
                        f"sonar: expected {n_sonar} ranges (one per unit), found {len(values)}",
                    )
                mm = np.asarray(values, dtype=np.float64)
                if (mm < 0).any():
                    raise self.error(line, "sonar: negative range")
                present = mm > 0  # 0 is no reading, as in sick<N>: lines
                stamps.append(np.full(int(present.sum()), block.stamp_ns, dtype=np.int64))
                index.append(offsets["sonar"] + np.nonzero(present)[0])
                ranges.append(mm[present] / 1000.0)
            for number in sorted(block.lasers):
                line, form, values = block.lasers[number]
                base = offsets[f"laser{number}"]
                laser = self.lasers[number]
                assert laser.conf is not None
                samples = laser.conf[2]
                rng = self.laser_ranges(line, form, number, values, samples, laser)
                keep = np.isfinite(rng)
                stamps.append(np.full(int(keep.sum()), block.stamp_ns, dtype=np.int64))
                index.append(base + np.nonzero(keep)[0])
                ranges.append(rng[keep])
        if not stamps:
            return RangeReadings(
                np.empty(0, np.int64), np.empty(0, np.int32), np.empty(0, np.float64)
            )
        return RangeReadings(
            stamp_ns=np.concatenate(stamps),
            sensor=np.concatenate(index).astype(np.int32),
            range_m=np.concatenate(ranges),
        )

    def sonar_readings(self, data: list[_Block], n_sonar: int, offset: int) -> RangeReadings:
        """:meth:`readings` of a log without laser lines, all blocks at once: the same
        readings in the same order, and the same first error."""
        lines = [b.sonar for b in data if b.sonar is not None]
        stamps = np.array([b.stamp_ns for b in data if b.sonar is not None], dtype=np.int64)
        wrong = next((i for i, (_, v) in enumerate(lines) if len(v) != n_sonar), len(lines))
        mm = np.array([v for _, v in lines[:wrong]], dtype=np.float64).reshape(wrong, n_sonar)
        negative = (mm < 0).any(axis=1)
        if negative.any():
            raise self.error(lines[int(np.argmax(negative))][0], "sonar: negative range")
        if wrong < len(lines):
            line, values = lines[wrong]
            raise self.error(
                line, f"sonar: expected {n_sonar} ranges (one per unit), found {len(values)}"
            )
        present = mm > 0  # 0 is no reading, as in sick<N>: lines
        block, unit = np.nonzero(present)
        return RangeReadings(
            stamp_ns=stamps[block],
            sensor=(offset + unit).astype(np.int32),
            range_m=mm[present] / 1000.0,
        )

    def laser_ranges(
        self, line: int, form: str, number: int, values: list[float], samples: int, laser: _Laser
    ) -> np.ndarray:
        """Range per beam in metres, NaN where the laser ignored the reading.

        With gridmap's ``sick<N>maxRange:`` line, a beam at or beyond that range is no echo and
        comes back as exactly the maximum (as no echo is stored everywhere); without it the
        ranges are taken as they are, as ARIA's own logs mean them.
        """
        rng = self.beam_ranges(line, form, number, values, samples, laser)
        if laser.max_range_m is not None:
            rng = np.minimum(rng, laser.max_range_m)  # NaN stays NaN
        return rng

    def beam_ranges(
        self, line: int, form: str, number: int, values: list[float], samples: int, laser: _Laser
    ) -> np.ndarray:
        """Range per beam in metres as the line holds it, NaN where the laser ignored it."""
        tag = f"{form}{number}"
        if form == "sick":
            if len(values) != samples:
                raise self.error(line, f"{tag}: expected {samples} ranges, found {len(values)}")
            mm = np.asarray(values, dtype=np.float64)
            if (mm < 0).any():
                raise self.error(line, f"{tag}: negative range")
            return np.where(mm > 0, mm / 1000.0, np.nan)
        if len(values) != 2 * samples:
            raise self.error(
                line, f"{tag}: expected {samples} x y pairs, found {len(values) / 2:g} pairs"
            )
        xy = np.asarray(values, dtype=np.float64).reshape(samples, 2) / 1000.0
        lx, ly, _ = laser.pose or (0.0, 0.0, 0.0)
        ignored = (xy[:, 0] == 0.0) & (xy[:, 1] == 0.0)
        dist = np.hypot(xy[:, 0] - lx, xy[:, 1] - ly)
        return np.where(ignored, np.nan, dist)
