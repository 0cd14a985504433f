"""Long CSV logs read without holding their readings: checked once, then read again per pass.

A build needs the readings twice (its bounds pass, its mapping pass) and never all at once, so a
log's readings need not be held: 20 bytes a reading, 92 MB for 8 hours of 16 sonars at 10 Hz,
with the text while it is parsed on top. A log of :data:`STREAM_FROM_BYTES` of text or more is
read here: a checking pass parses every row exactly as the bulk reader does
(:func:`gridmap_cli.readers.text.csv_log._read_bulk`), a piece of text at a time, and keeps the
stamps
and the pose tracks (one row's pose is 4 numbers against its 16 readings: 32 bytes a row, 56
with the truth) and each sensor's count of readings; the readings themselves are let go. Each
later pass reads the file again, piece by piece, and gives the same readings, bit for bit.

Whatever the bulk reader would leave to the row-by-row reader (a bad field, quotes, odd line
breaks) and whatever cannot be read (a corrupt gzip file, bytes that are not UTF-8) sends the log
to the held reader, which reads it whole and says what is wrong exactly as it always has
(``path:line: column ...``): all before a reading is mapped or a byte written.

Smaller logs are held, as before: a second parse costs more than the memory it saves there.
"""

from __future__ import annotations

import dataclasses
import gzip
import io
import itertools
import os
import zlib
from collections.abc import Iterator
from functools import partial
from pathlib import Path
from typing import TextIO

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import InputFileError
from gridmap_cli.limits import MAX_BLANK_LINES, MAX_LINE_CHARS, blank_lines
from gridmap_cli.readers.text.csv_log import (
    _ODD_BREAKS,
    POSE_COLUMNS,
    TRUTH_COLUMNS,
    _check_header,
    _log,
    _parse_block,
    before_header,
    seconds_to_ns,
)
from gridmap_cli.records import RangeLog, RangeReadings, ReadingStream

#: Logs of this much text or more (uncompressed) stream their readings. The bench's hour of 16
#: sonars is 5.4 MiB (576,000 readings) and stays held, as fast as ever; at 8 MiB a held log
#: peaks about 40 MiB above a streamed one in the reader, and the second parse (0.2 s a MiB of
#: text less the stamps, which are kept) is worth that.
STREAM_FROM_BYTES = 8 << 20
#: Text parsed at a time: about 400 rows (6,500 readings) of the bench's log; larger
#: pieces only hold more at once (1 MiB: 9 MiB more at the peak), no faster.
PIECE_CHARS = 1 << 16


class _NotPlain(Exception):
    """The log is not one the bulk reader takes whole: the held reader reads it."""


def read_streamed(path: Path, gz: bool) -> RangeLog | None:
    """The CSV log at ``path`` (gzip-compressed if ``gz``) with its readings streamed
    (:attr:`RangeLog.stream`); None when it is small or anything is not plainly well formed,
    for the held reader to read (and to report, with the line)."""
    try:
        if _text_bytes(path, gz) < STREAM_FROM_BYTES:
            return None
        seen = _stat(path)
        with _open(path, gz) as handle:
            return _check(handle, path, gz, seen)
    except (_NotPlain, OSError, EOFError, zlib.error, UnicodeDecodeError):
        return None


def _text_bytes(path: Path, gz: bool) -> int:
    size = path.stat().st_size
    if not gz or size < 4:
        return size
    with open(path, "rb") as handle:  # gzip's trailer: the text's size (mod 4 GiB)
        handle.seek(-4, os.SEEK_END)
        return max(size, int.from_bytes(handle.read(4), "little"))


def _stat(path: Path) -> tuple[int, int]:
    st = path.stat()
    return st.st_size, st.st_mtime_ns


def _open(path: Path, gz: bool) -> TextIO:
    """The text as the held reader reads it: a plain file's line ends as they are; a gzip
    file's decoded with universal newlines
    (:func:`gridmap_cli.readers.text.compressed.open_text`)."""
    if gz:
        return io.TextIOWrapper(gzip.open(path, "rb"), encoding="utf-8-sig", newline=None)
    return open(path, encoding="utf-8-sig", newline="")


def _pieces(handle: TextIO) -> Iterator[list[str]]:
    """The text's lines, split at ``\\n`` as the bulk reader splits the whole text, a piece of
    about :data:`PIECE_CHARS` at a time; raises :class:`_NotPlain` where the bulk reader would
    leave the text to the row reader (odd line breaks, a carriage return alone)."""
    tail = ""
    blank = 0
    while True:
        piece = handle.read(PIECE_CHARS)
        text = tail + piece
        cut = text.rfind("\n") + 1 if piece else len(text)
        if cut == 0 and piece:
            if len(text) > MAX_LINE_CHARS:
                raise _NotPlain  # the held reader refuses the line, with its number
            tail = text  # a line longer than a piece
            continue
        body, tail = text[:cut], text[cut:]
        if any(c in body for c in _ODD_BREAKS) or body.count("\r") != body.count("\r\n"):
            raise _NotPlain
        if body:
            lines = body.split("\n")
            blank += blank_lines(lines, len(body))
            if blank > MAX_BLANK_LINES:
                raise _NotPlain  # the held reader refuses it, with the line, after a piece
            yield lines
        if not piece:
            return


def _table(handle: TextIO) -> tuple[dict[str, str], list[str], Iterator[list[str]]]:
    """The ``# key: value`` metadata, the header and the data rows (blank ones left out, line
    ends stripped) in blocks of a piece."""
    pieces = _pieces(handle)
    metadata: dict[str, str] = {}
    for lines in pieces:
        for number, line in enumerate(lines):
            stripped = line.lstrip("\ufeff").strip()
            if before_header(stripped, metadata):
                continue
            header = [h.strip() for h in stripped.split(",")]
            return metadata, header, _rows(itertools.chain([lines[number + 1 :]], pieces))
    raise _NotPlain


def _rows(pieces: Iterator[list[str]]) -> Iterator[list[str]]:
    for lines in pieces:
        rows = [row for row in (line.rstrip("\r") for line in lines) if row.strip()]
        if rows:
            yield rows


def _check(handle: TextIO, path: Path, gz: bool, seen: tuple[int, int]) -> RangeLog:
    """The checking pass: every row parsed and checked as the bulk reader does; the stamps,
    pose tracks and per-sensor counts kept, the readings let go."""
    metadata, header, blocks = _table(handle)
    try:
        columns = _check_header(str(path), 0, header)
    except InputFileError:
        raise _NotPlain from None
    n_fields = len(header)
    time_col = header.index("time")
    pose_idx = [header.index(c) for c in POSE_COLUMNS[1:]]
    truth_idx = [header.index(c) for c in TRUTH_COLUMNS] if columns["truth"] else []
    sensor_cols = [i for i, h in enumerate(header) if h not in POSE_COLUMNS + TRUTH_COLUMNS]
    n_sensors = len(sensor_cols)
    counts = np.zeros(n_sensors, np.int64)
    first_ns = np.zeros(n_sensors, np.int64)
    last_ns = np.zeros(n_sensors, np.int64)
    stamp_parts: list[npt.NDArray[np.int64]] = []
    track_idx = pose_idx + truth_idx
    parts: list[list[npt.NDArray[np.float64]]] = [[] for _ in track_idx]  # per track column
    for rows in blocks:
        if any(row.count(",") != n_fields - 1 for row in rows):
            raise _NotPlain
        try:
            stamps = np.asarray(
                [seconds_to_ns(row.split(",", time_col + 1)[time_col]) for row in rows], np.int64
            )
        except ValueError:
            raise _NotPlain from None
        previous = stamp_parts[-1][-1:] if stamp_parts else stamps[:0]
        if not bool((np.diff(np.concatenate((previous, stamps))) > 0).all()):
            raise _NotPlain
        matrix = _parse_block(rows, n_fields)
        if matrix is None or not np.isfinite(matrix[:, pose_idx + truth_idx]).all():
            raise _NotPlain
        ranges = matrix[:, sensor_cols]
        if bool((ranges < 0.0).any()):
            raise _NotPlain
        has = ~np.isnan(ranges)
        found = has.any(axis=0)
        new = found & (counts == 0)
        first_ns[new] = stamps[np.argmax(has, axis=0)][new]
        last_ns[found] = stamps[len(rows) - 1 - np.argmax(has[::-1], axis=0)][found]
        counts += has.sum(axis=0)
        stamp_parts.append(stamps)
        for column, k in zip(parts, track_idx, strict=True):
            column.append(matrix[:, k].copy())  # not a view: the block's numbers go
    if not stamp_parts:
        raise _NotPlain
    stamp_arr = np.concatenate(stamp_parts)
    tracks = []
    for column in parts:  # one column at a time: never the whole table twice
        tracks.append(np.concatenate(column))
        column.clear()
    log = _log(str(path), header, metadata, stamp_arr, tracks, RangeReadings.empty(), sensor_cols)
    again = partial(_read_again, path, gz, seen, n_fields, sensor_cols, stamp_arr)
    index = np.arange(n_sensors, dtype=np.int32)
    stream = ReadingStream(again, counts, first_ns, last_ns, index)
    return dataclasses.replace(log, stream=stream)


def _read_again(
    path: Path,
    gz: bool,
    seen: tuple[int, int],
    n_fields: int,
    sensor_cols: list[int],
    stamp_ns: npt.NDArray[np.int64],
) -> Iterator[RangeReadings]:
    """The checked log's readings, read again block by block (a block never splits a row, so
    never a stamp); ``stamp_ns``: the rows' stamps, from the checking pass."""
    changed = InputFileError(path, "the file changed while gridmap read it")
    if _stat(path) != seen:
        raise changed
    first = 0
    try:
        with _open(path, gz) as handle:
            for rows in _table(handle)[2]:
                matrix = _parse_block(rows, n_fields)
                if matrix is None or first + len(rows) > len(stamp_ns):
                    raise changed
                ranges = matrix[:, sensor_cols]
                del matrix
                row_idx, sensor_idx = np.nonzero(~np.isnan(ranges))  # by stamp, then sensor
                yield RangeReadings(
                    stamp_ns[row_idx + first],
                    sensor_idx.astype(np.int32),
                    ranges[row_idx, sensor_idx],
                )
                first += len(rows)
    except (_NotPlain, OSError, EOFError, zlib.error, UnicodeDecodeError):
        raise changed from None
    if first != len(stamp_ns):
        raise changed
