"""Text logs from a path or an open handle, alike for every text reader (CSV, ARIA, CARMEN).

A reader parses an open text handle and names it in its errors (``run.csv:812: ...``); this
opens a path for it in the format's encoding, turns an unreadable file into one
:class:`~gridmap_cli.errors.InputFileError`, and names a handle given without a name by its own
``name`` attribute.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TextIO, TypeVar

from gridmap_cli.errors import InputFileError

T = TypeVar("T")


def parse_text(
    source: str | Path | TextIO,
    name: str | None,
    parse: Callable[[TextIO, str], T],
    encoding: str,
    newline: str | None = None,
) -> T:
    """``parse(handle, name)`` on ``source``: a path opened in ``encoding``, or an open handle.

    ASCII formats are read as latin-1, which decodes any byte, so that a stray byte is reported
    by the parser with its line rather than as undecodable text.
    """
    if isinstance(source, str | Path):
        path = str(source)
        try:
            with open(source, encoding=encoding, newline=newline) as handle:
                return parse(handle, path)
        except UnicodeDecodeError as exc:
            what = encoding.removesuffix("-sig").upper()  # utf-8-sig: UTF-8, BOM or not
            raise InputFileError(path, f"not {what} text ({exc.reason})") from exc
        except OSError as exc:
            raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from exc
    return parse(source, name or str(getattr(source, "name", "<stream>")))
