"""gzip-compressed text logs (``run.csv.gz``, ``intel.log.gz``, ``run.2d.gz``).

The registry decides the format from the inner extension, else by sniffing the decompressed
head; the text readers then read the decompressed text from a handle, so their error messages
still say ``run.log.gz:812: ...`` with the line number of the decompressed text. A file that is
not valid gzip (truncated, corrupt, not gzip at all) is an :class:`InputFileError` naming it.
"""

from __future__ import annotations

import gzip
import io
import zlib
from pathlib import Path

from gridmap_cli.errors import InputFileError

MAGIC = b"\x1f\x8b"
SUFFIX = ".gz"


def is_gzip(path: Path) -> bool:
    """True if ``path`` is meant to be gzip: named ``*.gz`` or starting with the gzip magic."""
    if path.suffix.lower() == SUFFIX:
        return True
    try:
        with open(path, "rb") as handle:
            return handle.read(2) == MAGIC
    except OSError:
        return False  # the reader reports the unreadable file


def inner_suffix(path: Path) -> str:
    """The extension under ``.gz`` (``.log`` for ``intel.log.gz``), lower case; '' if none."""
    if path.suffix.lower() != SUFFIX:
        return ""
    return Path(path.stem).suffix.lower()


def _decompress(path: Path, limit: int | None) -> bytes:
    try:
        with gzip.open(path, "rb") as handle:
            return handle.read() if limit is None else handle.read(limit)
    except (gzip.BadGzipFile, EOFError, zlib.error) as exc:
        detail = str(exc) or type(exc).__name__
        if isinstance(exc, EOFError):
            detail = "compressed data end early (truncated file?)"
        raise InputFileError(path, f"not a valid gzip file: {detail}") from None
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from exc


def decompress_bytes(data: bytes, name: str) -> bytes:
    """gzip data held in memory (a log on standard input), decompressed."""
    try:
        return gzip.decompress(data)
    except (gzip.BadGzipFile, EOFError, zlib.error) as exc:
        detail = str(exc) or type(exc).__name__
        if isinstance(exc, EOFError):
            detail = "compressed data end early (truncated?)"
        raise InputFileError(name, f"not a valid gzip stream: {detail}") from None


def head(path: Path, size: int) -> bytes:
    """The first ``size`` decompressed bytes, for sniffing."""
    return _decompress(path, size)


def open_text(path: Path, encoding: str) -> io.StringIO:
    """The whole decompressed text as a text handle.

    Decompressed in one go, so that a corrupt file fails here, before any parsing, with one
    line; ``encoding`` is the one the format's reader uses for plain files.
    """
    data = _decompress(path, None)
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError as exc:
        raise InputFileError(
            path, f"decompressed data is not {encoding} text ({exc.reason})"
        ) from exc
    return io.StringIO(text, newline=None)
