"""Reader for ARIA robot parameter files (``params/<robot>.p``, ``ConfigVersion 2.0``).

ARIA (MobileRobots' Advanced Robot Interface for Applications) describes a robot in a plain-text
file read by ``ArFileParser``/``ArConfig``::

    Section Sonar parameters
    SonarNum 16              ; Number of sonars on the robot.
    SonarUnit 0 147 136 90   ; <n> <x mm> <y mm> <heading deg> [MTX fields ...]

Syntax, as ARIA reads it: ``;`` starts a comment anywhere on a line; a line's first word is the
key (case-insensitive) and the words after it, up to the comment, are its value; an empty value
(``LaserType   ; Type of laser.``) means "not set"; ``Section <name>`` starts a section. Keys
gridmap does not use are ignored, as ARIA ignores keys it does not know; that includes the
fragments of comments that ARIA's writer wraps onto lines of their own without a ``;``.

What is read (ARIA units -> SI):

- ``Subclass``: robot name (else the file's stem).
- ``SonarNum``, ``SonarUnit <n> <x_mm> <y_mm> <heading_deg>``: the sonar ring; extra MTX fields
  after the heading are ignored.
- ``SonarMaxRange`` (mm): the first occurrence wins (it is per sonar board; the Pioneer ring is
  ``SonarBoard_1``); default 4335 mm, the range the file documents as ``range [0, 4335]``.
- ``RangeConvFactor``: multiplier from raw sonar units to mm (default 1.0); kept for readers of
  raw robot logs, it does not change the geometry.
- ``LaserAutoConnect``, ``LaserType``, ``LaserX``/``LaserY`` (mm), ``LaserTh`` (deg),
  ``LaserMaxRange`` (mm, 0 = the laser's default), per section ("Laser parameters", "Laser 2
  parameters", ...). ``LaserPossessed`` (pre-2.0 files) counts as ``LaserAutoConnect``.

Bytes are decoded as UTF-8, falling back to Latin-1: ARIA's parser reads bytes, and files written
by it are ASCII or Latin-1, so decoding never fails and only comments could differ.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

from gridmap_cli.errors import RobotDescriptionError
from gridmap_cli.limits import check_settings_size
from gridmap_cli.robot.description import RangeSensor, RobotDescription

DEFAULT_SONAR_MAX_RANGE_MM = 4335.0
"""ARIA's default sonar range: ``SonarMaxRange 4335 ; range [0, 4335]`` in the shipped files."""

DEFAULT_BEAM_WIDTH_DEG = 25.0
"""Sonar beam width used by the presets; ``.p`` files do not state one."""

DEFAULT_MIN_RANGE_M = 0.15
"""Sonar near limit used by the presets; ``.p`` files do not state one."""

# Keys whose presence (with "Section" headers) tells a parameter file from something else.
_KNOWN_KEYS = frozenset(
    {
        "configversion",
        "class",
        "subclass",
        "robotradius",
        "robotwidth",
        "robotlength",
        "angleconvfactor",
        "distconvfactor",
        "rangeconvfactor",
        "sonarnum",
        "sonarunit",
        "sonarmaxrange",
        "laserautoconnect",
        "laserpossessed",
        "lasertype",
        "laserx",
        "lasery",
        "laserth",
        "lasermaxrange",
    }
)
_LASER_KEYS = frozenset(k for k in _KNOWN_KEYS if k.startswith("laser"))
_TRUE = frozenset({"true", "1", "yes", "on"})
_FALSE = frozenset({"false", "0", "no", "off"})


@dataclass(frozen=True)
class AriaLaser:
    """A laser rangefinder that a parameter file section says is fitted.

    ``section``: the ARIA section it comes from (``"Laser parameters"``, ``"Laser 2 parameters"``).
    ``x_m``, ``y_m``: position in the robot base frame (x forward, y left), metres.
    ``yaw_rad``: rotation of the scan's zero direction, radians, counter-clockwise.
    ``max_range_m``: ``LaserMaxRange`` in metres, or None for the laser's own default (0 in ARIA).
    ``laser_type``: ARIA's laser type (``lms2xx``, ``urg``, ...), or None when left blank.
    ``auto_connect``: ``LaserAutoConnect`` (ARIA connects to it at startup).
    """

    section: str
    x_m: float
    y_m: float
    yaw_rad: float
    max_range_m: float | None
    laser_type: str | None
    auto_connect: bool


@dataclass(frozen=True)
class AriaRobotParams:
    """What gridmap uses of an ARIA robot parameter file, in SI units.

    ``source``: the file (or label) it was read from, for messages.
    ``name``: ``Subclass`` (``p3at``), else the file's stem.
    ``sonar_units``: ``(n, x_m, y_m, heading_rad)`` per ``SonarUnit``, ordered by ``n`` (0..N-1);
    position in the base frame (x forward, y left), metres; heading counter-clockwise, radians.
    ``sonar_max_range_m``: ``SonarMaxRange`` in metres (default 4.335).
    ``range_conv_factor``: ``RangeConvFactor``, mm per raw sonar unit (default 1.0).
    ``lasers``: the laser sections that describe a fitted laser (``LaserAutoConnect true`` or a
    non-empty ``LaserType``), in file order.
    """

    source: str
    name: str
    sonar_units: tuple[tuple[int, float, float, float], ...]
    sonar_max_range_m: float
    range_conv_factor: float
    lasers: tuple[AriaLaser, ...]

    def robot(
        self,
        beam_width_deg: float = DEFAULT_BEAM_WIDTH_DEG,
        min_range_m: float = DEFAULT_MIN_RANGE_M,
    ) -> RobotDescription:
        """The sonar ring as a :class:`RobotDescription`, sensors named ``sonar<n>``.

        ``beam_width_deg``: full opening angle of each sonar beam, degrees; ``min_range_m``: near
        limit, metres. Neither is in a ``.p`` file; the defaults are those of the ``p3at``/``p3dx``
        presets, so the real ``p3at.p`` gives exactly ``load_robot("p3at")``. Lasers are not
        included: gridmap maps sonar readings only (see :attr:`lasers`).
        """
        if not 0.0 <= beam_width_deg < 180.0:
            raise ValueError(f"beam_width_deg must be in [0, 180), got {beam_width_deg}")
        if not 0.0 <= min_range_m < self.sonar_max_range_m:
            raise RobotDescriptionError(
                self.source,
                f"need 0 <= minimum range ({min_range_m} m) < SonarMaxRange "
                f"({self.sonar_max_range_m} m)",
            )
        width_rad = math.radians(beam_width_deg)
        return RobotDescription(
            name=self.name,
            sensors=tuple(
                RangeSensor(
                    name=f"sonar{n}",
                    x_m=x_m,
                    y_m=y_m,
                    yaw_rad=heading_rad,
                    beam_width_rad=width_rad,
                    min_range_m=min_range_m,
                    max_range_m=self.sonar_max_range_m,
                    kind="sonar",
                )
                for n, x_m, y_m, heading_rad in self.sonar_units
            ),
        )


@dataclass(frozen=True)
class _Entry:
    """One ``Key value...`` line: original key spelling, value words, 1-based line, section."""

    key: str
    words: tuple[str, ...]
    line: int
    section: str


def read_aria_params(path: str | os.PathLike[str]) -> AriaRobotParams:
    """Read an ARIA robot parameter file; errors read ``path:line: ...``."""
    try:
        check_settings_size(Path(path), "a robot parameter file")
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise RobotDescriptionError(str(path), f"cannot read: {exc.strerror or exc}") from exc
    return parse_aria_params(_decode(raw), str(path))


def _decode(raw: bytes) -> str:
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    return text.removeprefix("\ufeff")


def parse_aria_params(text: str, source: str) -> AriaRobotParams:
    """Parse the text of an ARIA robot parameter file; ``source`` names it in error messages."""
    entries, saw_section = _tokenize(text)
    if not saw_section and not any(e.key.lower() in _KNOWN_KEYS for e in entries):
        first = _first_content_line(text)
        where = f": found {first[1][:40]!r}" if first else " (it is empty)"
        raise RobotDescriptionError(
            source,
            "not an ARIA robot parameter file: no 'Section' headers and no known keys "
            f"such as SonarUnit{where}",
            first[0] if first else None,
        )

    by_key: dict[str, list[_Entry]] = {}
    for e in entries:
        by_key.setdefault(e.key.lower(), []).append(e)

    def last(key: str) -> _Entry | None:
        # ARIA sets a key each time it meets it, so a repeated key's last value wins
        found = by_key.get(key)
        return found[-1] if found else None

    subclass = last("subclass")
    name = subclass.words[0] if subclass and subclass.words else Path(source).stem

    units = _sonar_units(source, by_key.get("sonarunit", []), last("sonarnum"), entries)

    max_range = by_key.get("sonarmaxrange")
    max_range_mm = DEFAULT_SONAR_MAX_RANGE_MM
    if max_range and max_range[0].words:
        max_range_mm = _float(source, max_range[0], "SonarMaxRange")
        if max_range_mm <= 0.0:
            raise RobotDescriptionError(
                source,
                f"SonarMaxRange must be positive (mm), got {max_range_mm:g}",
                max_range[0].line,
            )

    conv = last("rangeconvfactor")
    range_conv = 1.0
    if conv and conv.words:
        range_conv = _float(source, conv, "RangeConvFactor")
        if range_conv <= 0.0:
            raise RobotDescriptionError(
                source, f"RangeConvFactor must be positive, got {range_conv:g}", conv.line
            )

    return AriaRobotParams(
        source=source,
        name=name,
        sonar_units=units,
        sonar_max_range_m=max_range_mm / 1000.0,
        range_conv_factor=range_conv,
        lasers=_lasers(source, entries),
    )


def _tokenize(text: str) -> tuple[list[_Entry], bool]:
    """Split into key/value entries (comments removed); also whether any Section header was seen."""
    entries: list[_Entry] = []
    section = ""
    saw_section = False
    for number, raw in enumerate(text.splitlines(), start=1):
        body = raw.split(";", 1)[0]
        words = body.split()
        if not words:
            continue
        if words[0].lower() == "section":
            # the section name is the rest of the line, spaces included
            section = body.strip()[len(words[0]) :].strip()
            saw_section = True
            continue
        entries.append(_Entry(words[0], tuple(words[1:]), number, section))
    return entries, saw_section


def _first_content_line(text: str) -> tuple[int, str] | None:
    for number, raw in enumerate(text.splitlines(), start=1):
        if raw.strip():
            return number, raw.strip()
    return None


def _float(source: str, entry: _Entry, key: str, word: str | None = None) -> float:
    """``word`` (default: the entry's first value word) as a finite float, else an error."""
    text = entry.words[0] if word is None else word
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise RobotDescriptionError(source, f"{key}: not a number: {text!r}", entry.line)
    return value


def _int(source: str, entry: _Entry, key: str, word: str) -> int:
    try:
        return int(word)
    except ValueError:
        raise RobotDescriptionError(
            source, f"{key}: not a whole number: {word!r}", entry.line
        ) from None


def _sonar_units(
    source: str,
    lines: list[_Entry],
    sonar_num: _Entry | None,
    entries: list[_Entry],
) -> tuple[tuple[int, float, float, float], ...]:
    """Validate the SonarUnit lines against each other and SonarNum; sorted by unit number."""
    if not lines:
        anchor = sonar_num or next(
            (e for e in entries if e.section.lower().startswith("sonar")), None
        )
        raise RobotDescriptionError(
            source,
            "no SonarUnit lines: the file describes no sonar ring "
            "(expected 'SonarUnit <n> <x_mm> <y_mm> <heading_deg>')",
            anchor.line if anchor else None,
        )
    seen: dict[int, _Entry] = {}
    units: list[tuple[int, float, float, float]] = []
    for e in lines:
        if len(e.words) < 4:
            raise RobotDescriptionError(
                source,
                f"SonarUnit needs at least 4 fields <n> <x_mm> <y_mm> <heading_deg>, "
                f"got {len(e.words)}: {' '.join(e.words)!r}",
                e.line,
            )
        n = _int(source, e, "SonarUnit number", e.words[0])
        if n in seen:
            raise RobotDescriptionError(
                source, f"duplicate SonarUnit {n} (first on line {seen[n].line})", e.line
            )
        seen[n] = e
        x_mm, y_mm, heading_deg = (
            _float(source, e, f"SonarUnit {n} {what}", word)
            for what, word in zip(("x_mm", "y_mm", "heading_deg"), e.words[1:4], strict=True)
        )
        units.append((n, x_mm / 1000.0, y_mm / 1000.0, math.radians(heading_deg)))
    if sonar_num is not None and sonar_num.words:
        declared = _int(source, sonar_num, "SonarNum", sonar_num.words[0])
        if declared != len(units):
            raise RobotDescriptionError(
                source,
                f"SonarNum {declared} disagrees with the {len(units)} SonarUnit lines",
                sonar_num.line,
            )
    count = len(units)
    for n, e in seen.items():
        if not 0 <= n < count:
            missing = sorted(set(range(count)) - set(seen))
            raise RobotDescriptionError(
                source,
                f"SonarUnit {n}: units must be numbered 0..{count - 1}"
                f" (missing {', '.join(map(str, missing))})",
                e.line,
            )
    return tuple(sorted(units))


def _lasers(source: str, entries: list[_Entry]) -> tuple[AriaLaser, ...]:
    """One AriaLaser per section holding Laser* keys whose laser is fitted, in file order."""
    sections: dict[str, dict[str, _Entry]] = {}
    for e in entries:
        key = e.key.lower()
        if key in _LASER_KEYS:
            sections.setdefault(e.section, {})[key] = e
    out: list[AriaLaser] = []
    for section, keys in sections.items():

        def mm(key: str, spelled: str, keys: dict[str, _Entry] = keys) -> float:
            e = keys.get(key)
            return _float(source, e, spelled) if e and e.words else 0.0

        auto = _bool(source, keys.get("laserautoconnect"), "LaserAutoConnect") or _bool(
            source, keys.get("laserpossessed"), "LaserPossessed"
        )
        type_entry = keys.get("lasertype")
        laser_type = type_entry.words[0] if type_entry and type_entry.words else None
        x_mm = mm("laserx", "LaserX")
        y_mm = mm("lasery", "LaserY")
        th_deg = mm("laserth", "LaserTh")
        max_mm = mm("lasermaxrange", "LaserMaxRange")
        if max_mm < 0.0:
            raise RobotDescriptionError(
                source,
                f"LaserMaxRange must be >= 0 (mm; 0 = the laser's default), got {max_mm:g}",
                keys["lasermaxrange"].line,
            )
        if not auto and laser_type is None:
            continue
        out.append(
            AriaLaser(
                section=section,
                x_m=x_mm / 1000.0,
                y_m=y_mm / 1000.0,
                yaw_rad=math.radians(th_deg),
                max_range_m=max_mm / 1000.0 if max_mm > 0.0 else None,
                laser_type=laser_type,
                auto_connect=auto,
            )
        )
    return tuple(out)


def _bool(source: str, entry: _Entry | None, key: str) -> bool:
    if entry is None or not entry.words:
        return False
    word = entry.words[0].lower()
    if word in _TRUE:
        return True
    if word in _FALSE:
        return False
    raise RobotDescriptionError(
        source, f"{key}: expected true or false, got {entry.words[0]!r}", entry.line
    )
