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


class LimitError(InputFileError):
    """Input beyond one of gridmap's bounds: the message names the bound."""


def numbered_lines(handle: TextIO, path: str, start: int = 1) -> Iterator[tuple[int, str]]:
    """``enumerate(handle, start)``, refusing a line longer than :data:`MAX_LINE_CHARS` after
    reading at most that many characters of it."""
    number = start - 1
    while True:
        line = handle.readline(MAX_LINE_CHARS + 1)
        if not line:
            return
        number += 1
        if len(line) > MAX_LINE_CHARS:
            raise LimitError(
                path,
                f"line longer than {MAX_LINE_CHARS:,} characters, gridmap's limit for one line "
                "of a text log (MAX_LINE_CHARS); not a log, or a damaged one",
                number,
            )
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
