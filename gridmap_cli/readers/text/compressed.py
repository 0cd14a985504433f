"""gzip-compressed text logs (``run.csv.gz``, ``intel.log.gz``, ``run.2d.gz``).

The registry decides the format from the inner extension, else by sniffing the decompressed
head; the text readers then read the decompressed text from a handle, so their error messages
still say ``run.log.gz:812: ...`` with the line number of the decompressed text. A file that is
not valid gzip (truncated, corrupt, not gzip at all) is an :class:`InputFileError` naming it.
"""

from __future__ import annotations

import io
import zlib
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import BinaryIO

from gridmap_cli.errors import InputFileError
from gridmap_cli.limits import MAX_BLANK_LINES, MAX_LINE_CHARS, too_long, too_many_blank

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


#: Decompressed bytes produced per step, and the input read per step.
_PIECE_BYTES = 1 << 20
#: A run of more bytes than this without a line break holds a line longer than the readers'
#: limit in any encoding (a character is at most 4 bytes): refused while decompressing, so a
#: gzip bomb (gigabytes of NULs, one endless line) stops after a few MiB.
MAX_RUN_BYTES = 4 * MAX_LINE_CHARS


def _inflate(chunks: Iterable[bytes], name: str, limit: int | None = None) -> bytes:
    """The gzip members in ``chunks`` decompressed, refusing an over-long line as it is made.

    ``limit``: stop after that many bytes (a head to sniff). Raises :class:`LimitError` naming
    the line, :class:`InputFileError` for data that are not gzip or end early.
    """
    inflater = zlib.decompressobj(wbits=31)
    out: list[bytes] = []
    size = run = blank = 0
    lines = 1
    started = False
    for chunk in chunks:
        data = chunk
        while data:
            started = True
            piece = inflater.decompress(data, _PIECE_BYTES)
            data = inflater.unconsumed_tail
            if inflater.eof:
                rest = inflater.unused_data  # at the end, the input left (the tail repeats it)
                data = b"" if not rest.strip(b"\0") else rest  # padding, or the next member
                if data:
                    inflater = zlib.decompressobj(wbits=31)
            elif not data and len(piece) == _PIECE_BYTES:
                piece += _drain(inflater)
            run, empty = _check(piece, run, name, lines)
            blank += empty
            if blank > MAX_BLANK_LINES:
                raise too_many_blank(name, lines + piece.count(b"\n"))
            lines += piece.count(b"\n")
            out.append(piece)
            size += len(piece)
            if limit is not None and size >= limit:
                return b"".join(out)[:limit]
    if started and not inflater.eof:
        raise InputFileError(name, "not a valid gzip file: compressed data end early (truncated?)")
    return b"".join(out)


def _drain(inflater: zlib._Decompress) -> bytes:
    """Output ``inflater`` still holds once its input is all taken (a piece filled exactly)."""
    more = []
    while not inflater.eof:
        piece = inflater.decompress(b"", _PIECE_BYTES)
        if not piece:
            break
        more.append(piece)
        if sum(map(len, more)) > MAX_RUN_BYTES:
            break  # checked by the caller; the rest comes with the next input
    return b"".join(more)


def _check(piece: bytes, run: int, name: str, lines: int) -> tuple[int, int]:
    """The run without a line break (``\n`` or a lone ``\r``) at the end of ``piece``, given
    ``run`` before it, and the piece's blank lines where its lines average under 4 bytes (a
    log's never do: :func:`~gridmap_cli.limits.blank_lines`); raises :class:`LimitError` at the
    first run over the bound."""
    parts = piece.replace(b"\r", b"\n").split(b"\n")
    lengths = list(map(len, parts))
    lengths[0] += run
    if max(lengths) > MAX_RUN_BYTES:
        offset = 0
        for j, part in enumerate(parts):
            if lengths[j] > MAX_RUN_BYTES:
                raise too_long(name, lines + piece.count(b"\n", 0, offset))
            offset += len(part) + 1
    blank = 0
    if 4 * len(parts) > len(piece):
        blank = sum(1 for part in parts if not part.strip())
    return lengths[-1], blank


def _file_chunks(handle: BinaryIO) -> Iterator[bytes]:
    while chunk := handle.read(_PIECE_BYTES):
        yield chunk


def _decompress(path: Path, limit: int | None) -> bytes:
    try:
        with open(path, "rb") as handle:
            return _inflate(_file_chunks(handle), str(path), limit)
    except zlib.error as exc:
        raise InputFileError(path, f"not a valid gzip file: {exc}") from None
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from exc


def decompress_bytes(data: bytes, name: str) -> bytes:
    """gzip data held in memory (a log on standard input), decompressed."""
    try:
        view = memoryview(data)
        pieces = (bytes(view[i : i + _PIECE_BYTES]) for i in range(0, len(data), _PIECE_BYTES))
        return _inflate(pieces, name)
    except zlib.error as exc:
        raise InputFileError(name, f"not a valid gzip stream: {exc}") from None


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
