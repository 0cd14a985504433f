"""Bounds on what one line, one file of settings and one robot may hold.

A log nobody checked can hold a line of 50 million fields or a robot declaring a laser of 10^8
beams; read naively, either runs the machine out of memory or takes minutes. Each bound here is
far above anything a real recording holds, is checked before the memory is spent, and is named
in the error so that a user who really needs more knows what to change.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

from gridmap_cli.errors import InputFileError

#: Characters in one line of a text log (CSV, ARIA, CARMEN): a 1081-beam laser line is ~10 KB.
MAX_LINE_CHARS = 1 << 20
#: Bytes of a YAML or ARIA .p file of settings (robot, world, path, odometry error, metadata).
MAX_SETTINGS_BYTES = 4 << 20
#: Beams of one scanning laser in a robot description (real lasers: up to a few thousand).
MAX_LASER_SAMPLES = 100_000
#: Empty (or blank) lines in one text log: a real one has a handful. Each costs a line's work
#: and a list slot, so a gzip of a few GiB of newlines would cost minutes and gigabytes.
MAX_BLANK_LINES = 1_000_000


class LimitError(InputFileError):
    """Input beyond one of gridmap's bounds: the message names the bound."""


#: Characters read at a time by :func:`read_bounded_text`.
_PIECE_CHARS = 1 << 22


def too_many_beams(path: str, beams: int, line: int | None = None, where: str = "") -> LimitError:
    """A scan of ``beams`` beams, above :data:`MAX_LASER_SAMPLES`; ``where`` places it in a
    recording (``/scan at log time 1.2 s: ``), ``line`` in a text log."""
    return LimitError(
        path,
        f"{where}a scan of {beams:,} beams, above gridmap's limit of {MAX_LASER_SAMPLES:,} beams "
        "per laser (MAX_LASER_SAMPLES)",
        line,
    )


def too_long(path: str, line: int) -> LimitError:
    return LimitError(
        path,
        f"line longer than {MAX_LINE_CHARS:,} characters, gridmap's limit for one line "
        "of a text log (MAX_LINE_CHARS); not a log, or a damaged one",
        line,
    )


def too_many_blank(path: str, line: int) -> LimitError:
    return LimitError(
        path,
        f"more than {MAX_BLANK_LINES:,} empty lines, gridmap's limit for a text log "
        "(MAX_BLANK_LINES); not a log, or a damaged one",
        line,
    )


def blank_lines(runs: list[str], chars: int) -> int:
    """Blank lines among ``runs`` (a piece of ``chars`` characters split at line breaks),
    counted only where the piece's lines average under 4 characters: a log's lines are longer,
    so its pieces cost nothing here."""
    if 4 * len(runs) <= chars:
        return 0
    return sum(1 for r in runs if not r.strip())


def read_bounded_text(handle: TextIO, path: str) -> str:
    """All of ``handle``'s text, refusing a line longer than :data:`MAX_LINE_CHARS` (counted
    between ``\\n`` or ``\\r`` breaks; numbered by ``\\n``) as soon as it is seen, after
    reading at most a few MiB past its start: a file of one endless line costs that, not its size.
    """
    pieces: list[str] = []
    run = 0  # characters of the line the last piece ended in
    newlines = 0
    blank = 0
    while True:
        piece = handle.read(_PIECE_CHARS)
        if not piece:
            return "".join(pieces)
        runs = piece.replace("\r", "\n").split("\n")
        blank += blank_lines(runs, len(piece))
        if blank > MAX_BLANK_LINES:
            raise too_many_blank(path, newlines + piece.count("\n") + 1)
        if run + len(runs[0]) > MAX_LINE_CHARS:
            raise too_long(path, newlines + 1)
        if len(runs) > 1:
            longest = max(range(1, len(runs) - 1), key=lambda i: len(runs[i]), default=None)
            if longest is not None and len(runs[longest]) > MAX_LINE_CHARS:
                raise too_long(path, newlines + piece.count("\n", 0, _offset(runs, longest)) + 1)
            run = len(runs[-1])
        else:
            run += len(runs[0])
        newlines += piece.count("\n")
        if run > MAX_LINE_CHARS:
            raise too_long(path, newlines + 1)
        pieces.append(piece)


def _offset(runs: list[str], index: int) -> int:
    """Where run ``index`` starts in the piece the runs were split from."""
    return sum(len(r) + 1 for r in runs[:index])


def numbered_lines(handle: TextIO, path: str, start: int = 1) -> Iterator[tuple[int, str]]:
    """``enumerate(handle, start)``, refusing a line longer than :data:`MAX_LINE_CHARS` after
    reading at most that many characters of it."""
    number = start - 1
    blank = 0
    while True:
        line = handle.readline(MAX_LINE_CHARS + 1)
        if not line:
            return
        number += 1
        if len(line) > MAX_LINE_CHARS:
            raise too_long(path, number)
        if len(line) < 8 and not line.strip():
            blank += 1
            if blank > MAX_BLANK_LINES:
                raise too_many_blank(path, number)
        yield number, line


def check_settings_size(path: Path, what: str) -> None:
    """Refuse a settings file (YAML, ARIA .p) beyond :data:`MAX_SETTINGS_BYTES` before reading
    it. Raises OSError as ``stat`` does."""
    size = path.stat().st_size
    if size > MAX_SETTINGS_BYTES:
        raise LimitError(
            path,
            f"{size:,} bytes, above gridmap's limit of {MAX_SETTINGS_BYTES:,} for {what} "
            "(MAX_SETTINGS_BYTES)",
        )


def read_settings_text(path: Path, what: str) -> str:
    """The text of a settings file, refused unread beyond :data:`MAX_SETTINGS_BYTES`. Raises
    OSError and UnicodeDecodeError as ``read_text`` does."""
    check_settings_size(path, what)
    return path.read_text(encoding="utf-8")
