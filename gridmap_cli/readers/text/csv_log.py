"""Reader for gridmap's CSV log layout (``schemas/csv-log.md``).

Optional leading ``# key: value`` comment lines, then a header row, then one row per odometry
stamp: ``time`` (s), ``x``, ``y`` (m), ``theta`` (rad), one column per range sensor (metres; empty
or ``nan`` = no reading) and optionally ``true_x``, ``true_y``, ``true_theta`` (ground truth).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TextIO

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import InputFileError
from gridmap_cli.limits import numbered_lines, read_bounded_text
from gridmap_cli.readers.text.source import parse_text
from gridmap_cli.records import PoseTrack, RangeLog, RangeReadings

POSE_COLUMNS = ("time", "x", "y", "theta")
TRUTH_COLUMNS = ("true_x", "true_y", "true_theta")
_NO_READING = ("", "nan", "NaN", "NAN")


def sniff(head: bytes) -> bool:
    """True if the first bytes look like a gridmap CSV log (comment block or header with time)."""
    text = head.decode("utf-8-sig", errors="replace")
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        return [c.strip() for c in line.split(",")][:1] == ["time"]
    return False


#: Nanoseconds an int64 stamp holds: about 292 years either side of its zero.
_MAX_STAMP_NS = 2**63 - 1


def seconds_to_ns(text: str) -> int:
    """Parse a decimal number of seconds into integer nanoseconds, exactly where it can.

    Plain decimals (``12.3``, ``-0.5``, ``1700000000.123456789``) are converted digit by digit, so
    epoch stamps keep their nanoseconds; other float spellings (``1e3``) go through float.
    Raises ValueError, whose message is what a caller shows after the field's name, for text
    that is not a finite number (``not a number: 'x'``) or a time no int64 nanosecond stamp
    holds (``1e300``).
    """
    s = text.strip()
    neg = s.startswith("-")
    body = s[1:] if s[:1] in "+-" else s
    whole, _, frac = body.partition(".")
    plain = (whole or frac) and all(part.isdigit() or not part for part in (whole, frac))
    try:
        if plain and body.isascii():
            if len(frac) > 9 and frac[9:].strip("0"):
                value = round(float(s) * 1e9)
            else:
                value = int(whole or "0") * 1_000_000_000 + int((frac + "000000000")[:9])
                value = -value if neg else value
        else:
            f = float(s)
            if not math.isfinite(f):
                raise ValueError
            value = round(f * 1e9) if math.isfinite(f * 1e9) else _MAX_STAMP_NS + 1
    except (ValueError, OverflowError):
        raise ValueError(f"not a number: {text!r}") from None
    if abs(value) > _MAX_STAMP_NS:
        raise ValueError(
            f"{text!r} s is beyond what a nanosecond stamp holds (about 292 years from zero)"
        )
    return value


def read_csv_log(source: str | Path | TextIO, name: str | None = None) -> RangeLog:
    """Read a CSV log from a path or an open text handle; ``name`` names a handle in errors.

    Raises :class:`InputFileError` with ``path:line`` for anything malformed: missing columns,
    non-numeric or NaN poses, time not increasing, wrong field counts, negative ranges.
    """
    return parse_text(source, name, _read, "utf-8-sig", newline="")


def _read(handle: TextIO, path: str) -> RangeLog:
    """Parse in bulk (:func:`_read_bulk`); when anything is off, the row-by-row reader below
    finds the bad field and says where (``path:line: column``)."""
    text = read_bounded_text(handle, path)
    return _read_bulk(text, path) or _read_rows(io.StringIO(text), path)


#: Characters other than \n that end a line for str.splitlines but not for the csv module: a
#: text holding any is left to the row-by-row reader.
_ODD_BREAKS = ("\v", "\f", "\x1c", "\x1d", "\x1e", "\x85", "\u2028", "\u2029", '"', "\r\r")


def _read_bulk(text: str, path: str) -> RangeLog | None:
    """The log, parsed with numpy in one go; None when the text is not plainly well formed.

    Plainly well formed: no quotes, every data line with the header's number of fields, numbers
    numpy parses, increasing times, finite poses, no negative ranges. The row reader gives the
    same log for such a text (tests/readers/test_csv_log.py checks) and the errors for others.
    """
    if any(c in text for c in _ODD_BREAKS) or text.count("\r") != text.count("\r\n"):
        return None
    metadata: dict[str, str] = {}
    lines = text.split("\n")
    header: list[str] | None = None
    start = 0
    for number, line in enumerate(lines):
        stripped = line.lstrip("\ufeff").strip()
        if before_header(stripped, metadata):
            continue
        header = [h.strip() for h in stripped.split(",")]
        start = number + 1
        break
    if header is None:
        return None
    try:
        columns = _check_header(path, start, header)
    except InputFileError:
        return None
    rows = [line.rstrip("\r") for line in lines[start:]]
    rows = [row for row in rows if row.strip()]
    n_fields = len(header)
    if not rows or any(row.count(",") != n_fields - 1 for row in rows):
        return None
    time_col = header.index("time")
    try:
        stamps = [seconds_to_ns(row.split(",", time_col + 1)[time_col]) for row in rows]
    except ValueError:
        return None
    stamp_arr = np.asarray(stamps, dtype=np.int64)
    del stamps
    if len(stamp_arr) > 1 and not bool((np.diff(stamp_arr) > 0).all()):
        return None
    pose_idx = [header.index(c) for c in POSE_COLUMNS[1:]]
    truth_idx = [header.index(c) for c in TRUTH_COLUMNS] if columns["truth"] else []
    sensor_cols = [i for i, h in enumerate(header) if h not in POSE_COLUMNS + TRUTH_COLUMNS]
    tracks: list[npt.NDArray[np.float64]] = []
    # the readings go straight into arrays of the most there can be, not into per-block pieces
    # joined at the end (which held them twice)
    most = len(rows) * len(sensor_cols)
    stamp_ns, sensor, range_m = np.empty(most, np.int64), np.empty(most, np.int32), np.empty(most)
    filled = 0
    for first in range(0, len(rows), _BLOCK_ROWS):
        matrix = _parse_block(rows[first : first + _BLOCK_ROWS], n_fields)
        if matrix is None or not np.isfinite(matrix[:, pose_idx + truth_idx]).all():
            return None
        ranges = matrix[:, sensor_cols]
        if bool((ranges < 0.0).any()):
            return None
        row_idx, sensor_idx = np.nonzero(~np.isnan(ranges))  # row-major: by stamp, then sensor
        tracks.append(matrix[:, pose_idx + truth_idx])
        end = filled + row_idx.shape[0]
        stamp_ns[filled:end] = stamp_arr[row_idx + first]
        sensor[filled:end] = sensor_idx
        range_m[filled:end] = ranges[row_idx, sensor_idx]
        filled = end
    keep = slice(0, filled)
    found = RangeReadings(stamp_ns[keep], sensor[keep], range_m[keep])
    if filled < most // 2:  # a sparse table: do not hold the empty half
        found = RangeReadings(found.stamp_ns.copy(), found.sensor.copy(), found.range_m.copy())
    table = np.concatenate(tracks)
    track_columns = [table[:, k] for k in range(table.shape[1])]
    return _log(path, header, metadata, stamp_arr, track_columns, found, sensor_cols)


#: Rows parsed at a time: the text, its numbers and their readings are never all held at once
#: (an 8 h log, 288,000 rows, peaked at 500 MiB parsed in one go).
_BLOCK_ROWS = 20_000


def _parse_block(rows: list[str], n_fields: int) -> npt.NDArray[np.float64] | None:
    """The rows' numbers, shape (len(rows), n_fields), NaN for an empty field; None when numpy
    does not read exactly that many numbers."""
    body = ",".join(rows)
    # an empty field is no reading; numpy's parser wants a word for it
    body = body.replace(",,", ",nan,").replace(",,", ",nan,")
    if body.endswith(","):
        body += "nan"
    try:
        values = np.fromstring(body, sep=",")
    except ValueError:
        return None
    if values.shape[0] != len(rows) * n_fields:
        return None
    return values.reshape(len(rows), n_fields)


def _log(
    path: str,
    header: list[str],
    metadata: dict[str, str],
    stamp_arr: npt.NDArray[np.int64],
    tracks: list[npt.NDArray[np.float64]],
    readings: RangeReadings,
    sensor_cols: list[int],
) -> RangeLog:
    """The RangeLog of a parsed table: ``tracks``, 3 or 6 columns of shape (rows,), the pose
    columns (x, y, theta, then the truth's)."""

    def track(first: int) -> PoseTrack:
        return PoseTrack(
            stamp_ns=stamp_arr,
            x_m=np.ascontiguousarray(tracks[first]),
            y_m=np.ascontiguousarray(tracks[first + 1]),
            theta_rad=np.ascontiguousarray(tracks[first + 2]),
        )

    return RangeLog(
        source=path,
        poses=track(0),
        readings=readings,
        sensor_names=tuple(header[i] for i in sensor_cols),
        truth=track(3) if len(tracks) == 6 else None,
        metadata=metadata,
        names_are_columns=True,
    )


def _read_rows(handle: TextIO, path: str) -> RangeLog:
    metadata: dict[str, str] = {}
    lines = numbered_lines(handle, path)
    header: list[str] | None = None
    header_line = 0
    for number, line in lines:
        # a BOM survives when the caller opened the file without utf-8-sig
        stripped = line.lstrip("\ufeff").strip()
        if before_header(stripped, metadata):
            continue
        try:
            header = next(csv.reader(io.StringIO(stripped)))
        except csv.Error as exc:  # e.g. a lone carriage return inside the line
            raise InputFileError(path, f"unreadable header row ({exc})", number) from exc
        header = [h.strip() for h in header]
        header_line = number
        break
    if header is None:
        raise InputFileError(path, "no header row (expected columns time,x,y,theta,...)")
    columns = _check_header(path, header_line, header)
    n_fields = len(header)
    sensor_cols = [i for i, h in enumerate(header) if h not in POSE_COLUMNS + TRUTH_COLUMNS]
    pose_idx = [header.index(c) for c in POSE_COLUMNS]
    truth_idx = [header.index(c) for c in TRUTH_COLUMNS] if columns["truth"] else []

    stamps: list[int] = []
    pose_rows: list[tuple[float, float, float]] = []
    truth_rows: list[tuple[float, float, float]] = []
    sensor_rows: list[list[float]] = []
    # csv.reader counts the physical lines it consumed; offset by the lines before the data
    rows = csv.reader(line for _, line in lines)
    line_no = header_line
    for fields in _csv_rows(rows, path, header_line):
        line_no = rows.line_num + header_line
        if not fields or (len(fields) == 1 and not fields[0].strip()):
            continue
        if len(fields) != n_fields:
            hint = " (truncated file?)" if len(fields) < n_fields else ""
            raise InputFileError(
                path, f"expected {n_fields} fields, found {len(fields)}{hint}", line_no
            )
        try:
            stamp = seconds_to_ns(fields[pose_idx[0]])
        except ValueError as exc:
            raise InputFileError(path, str(exc), line_no, "time") from None
        if stamps and stamp <= stamps[-1]:
            what = "repeats" if stamp == stamps[-1] else "goes backwards"
            raise InputFileError(
                path,
                f"time {what}: {fields[pose_idx[0]].strip()} s after "
                f"{stamps[-1] / 1e9:.9g} s (rows must be in increasing time)",
                line_no,
                "time",
            )
        stamps.append(stamp)
        pose_rows.append(_pose(path, line_no, fields, pose_idx[1:], POSE_COLUMNS[1:]))
        if truth_idx:
            truth_rows.append(_pose(path, line_no, fields, truth_idx, TRUTH_COLUMNS))
        sensor_rows.append([_range(path, line_no, fields[i], header[i]) for i in sensor_cols])
    if not stamps:
        raise InputFileError(path, "no data rows after the header", line_no)

    stamp_arr = np.asarray(stamps, dtype=np.int64)
    poses = PoseTrack.from_rows(stamp_arr, pose_rows)
    truth = PoseTrack.from_rows(stamp_arr, truth_rows) if truth_idx else None
    if sensor_cols:
        matrix = np.asarray(sensor_rows, dtype=np.float64).reshape(len(stamps), len(sensor_cols))
    else:
        matrix = np.empty((len(stamps), 0), dtype=np.float64)
    present = ~np.isnan(matrix)
    row_idx, sensor_idx = np.nonzero(present)  # row-major: by stamp, then sensor order
    readings = RangeReadings(
        stamp_ns=stamp_arr[row_idx],
        sensor=sensor_idx.astype(np.int32),
        range_m=matrix[row_idx, sensor_idx],
    )
    return RangeLog(
        source=path,
        poses=poses,
        readings=readings,
        sensor_names=tuple(header[i] for i in sensor_cols),
        truth=truth,
        metadata=metadata,
        names_are_columns=True,
    )


def before_header(stripped: str, metadata: dict[str, str]) -> bool:
    """Whether a stripped line before the header row is blank or a ``# key: value`` comment
    (kept in ``metadata``): the readers skip these until the header."""
    if stripped.startswith("#"):
        key, sep, value = stripped[1:].partition(":")
        if sep and key.strip():
            metadata[key.strip()] = value.strip()
        return True
    return not stripped


def _csv_rows(rows: Any, path: str, header_line: int) -> Iterator[list[str]]:
    """The rows of a ``csv.reader``, its own errors (a lone carriage return inside a row) as
    :class:`InputFileError` at the line they stopped on."""
    while True:
        try:
            fields = next(rows)
        except StopIteration:
            return
        except csv.Error as exc:
            raise InputFileError(
                path, f"unreadable row ({exc})", rows.line_num + header_line
            ) from exc
        yield fields


def _check_header(path: str, line: int, header: list[str]) -> dict[str, bool]:
    missing = [c for c in POSE_COLUMNS if c not in header]
    if missing:
        raise InputFileError(
            path,
            f"missing required column{'s' if len(missing) > 1 else ''} "
            f"{', '.join(repr(m) for m in missing)} (header has: {', '.join(header)})",
            line,
        )
    seen: set[str] = set()
    for h in header:
        if not h:
            raise InputFileError(path, "empty column name in the header", line)
        if h in seen:
            raise InputFileError(path, f"column {h!r} appears twice in the header", line)
        seen.add(h)
    truth = [c for c in TRUTH_COLUMNS if c in header]
    if truth and len(truth) != len(TRUTH_COLUMNS):
        absent = [c for c in TRUTH_COLUMNS if c not in header]
        raise InputFileError(
            path, f"ground truth needs all of true_x, true_y, true_theta; missing {absent}", line
        )
    return {"truth": bool(truth)}


def _pose(
    path: str, line: int, fields: list[str], idx: list[int], names: tuple[str, ...]
) -> tuple[float, float, float]:
    out = []
    for i, name in zip(idx, names, strict=True):
        text = fields[i].strip()
        try:
            value = float(text)
        except ValueError:
            raise InputFileError(path, f"not a number: {fields[i]!r}", line, name) from None
        if not math.isfinite(value):
            raise InputFileError(path, f"pose must be finite, got {text!r}", line, name)
        out.append(value)
    return out[0], out[1], out[2]


def _range(path: str, line: int, field: str, name: str) -> float:
    text = field.strip()
    if text in _NO_READING:
        return math.nan
    try:
        value = float(text)
    except ValueError:
        raise InputFileError(path, f"not a number: {field!r}", line, name) from None
    if math.isnan(value):
        return math.nan
    if value < 0.0:
        raise InputFileError(path, f"negative range {text} m", line, name)
    return value
