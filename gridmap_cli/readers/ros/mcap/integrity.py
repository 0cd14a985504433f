"""Check an MCAP file's structure and every CRC it carries before any message is trusted.

The ``mcap`` library checks no CRC unless asked, trusts length fields and lets a decompressor's
own exception escape. This module walks the file's records once, streaming, and refuses the
file at the first damage it finds, naming the byte offset:

- every record's length must fit in what is left of the file (or of its chunk);
- a chunk's compression must be known, its records length must fill the chunk record, it must
  decompress to exactly its ``uncompressed_size`` (at most :data:`MAX_CHUNK_BYTES`), and the
  CRC-32 of the decompressed records must equal ``uncompressed_crc`` (when not zero; see below
  for files with a data section CRC);
- inside a chunk, only schema, channel and message records, each fitting in the chunk;
- the data section's CRC (``DataEnd.data_section_crc``, when not zero) over every byte from the
  magic up to the DataEnd record;
- the summary's CRC (``Footer.summary_crc``, when not zero) from the summary's start through the
  footer's ``summary_offset_start`` field;
- every chunk index must point at a chunk found in the data section, with its length;
- attachments' CRCs.

A zero CRC means "not computed" (the specification's rule), so files written without CRCs pass.

When the data section's CRC is written, it covers every byte of every chunk as stored, so a
damaged chunk cannot pass it: the chunks' own CRCs (over their decompressed records, the larger
part of the walk's work) are then left until damage is found, and checked only to name the
first damaged chunk, as checking each at once would have. A chunk whose stored CRC disagrees
with its intact bytes (a writer's fault, not damage) then passes.

Why not the ``mcap`` reader's own ``validate_crcs``: it checks
the chunk CRCs and, in its stream reader only, the data section's CRC, but not the rest of what
this walk guarantees. ``Attachment.read`` skips the attachment's CRC unread, nothing reads
``Footer.summary_crc``, and its ``CRCValidationError`` says "crc validation failed in Chunk,
expected: X, calculated: Y" with no byte offset (its records do not know where they were read
from). A changed byte in an attachment or in the summary passes it without a word; here they
are "byte N: attachment CRC mismatch" and "byte N: summary CRC mismatch". The record walk
stays ours, with its compiled loop (``_cwalk.c``).
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

from gridmap_cli.errors import DamagedAtError, InputFileError
from gridmap_cli.readers.ros.walk import compiled_walk

MAGIC = b"\x89MCAP0\r\n"
#: The largest chunk gridmap decompresses (bytes of records once decompressed). Writers use
#: chunks of a few MiB; a chunk claiming more is far more likely a lie than a recording.
MAX_CHUNK_BYTES = 512 * 1024 * 1024

_HEADER, _FOOTER, _SCHEMA, _CHANNEL, _MESSAGE, _CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
_CHUNK_INDEX, _ATTACHMENT, _DATA_END = 0x08, 0x09, 0x0F
_IN_CHUNK = (_SCHEMA, _CHANNEL, _MESSAGE)
_IN_CHUNK_BYTES = bytes(_IN_CHUNK)
_FOOTER_LENGTH = 20  # summary_start u64, summary_offset_start u64, summary_crc u32
_MESSAGE_FIXED = 22  # channel_id u16, sequence u32, log_time u64, publish_time u64
_BLOCK = 1 << 20


class McapDamage(DamagedAtError):
    """An MCAP file is damaged at a byte offset: ``path: byte N: detail``."""


def verify_mcap(path: Path, take_chunk: Callable[[int, bytes], None] | None = None) -> None:
    """Raise :class:`McapDamage` at the first structural damage or CRC mismatch in ``path``.

    ``take_chunk``, when given, gets each chunk's offset in the file and its decompressed
    records once they are checked, in file order (so a reader needs not decompress them again).
    Raises :class:`InputFileError` when the file cannot be read. Memory use is bounded by the
    largest chunk (:data:`MAX_CHUNK_BYTES`).
    """
    try:
        with open(path, "rb") as handle:
            _Walker(path, handle, take_chunk).walk()
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from exc


def summary_intact(path: Path) -> bool:
    """Whether ``path`` ends in an MCAP footer whose summary CRC, when written, matches: the
    part of the file a survey reads. False when anything there is off (:func:`verify_mcap`
    then names the damage, or the first damage before it).
    """
    try:
        with open(path, "rb") as handle:
            handle.seek(0, 2)
            footer_at = handle.tell() - len(MAGIC) - 9 - _FOOTER_LENGTH
            if footer_at < len(MAGIC):
                return False
            handle.seek(footer_at)
            tail = handle.read()
            head = struct.unpack_from("<BQ", tail)
            if head != (_FOOTER, _FOOTER_LENGTH) or tail[-len(MAGIC) :] != MAGIC:
                return False
            summary_start, _, stored = struct.unpack_from("<QQI", tail, 9)
            if not stored:
                return True
            first = summary_start or footer_at
            if first > footer_at:
                return False
            handle.seek(first)
            return bool(_crc(handle, footer_at + 9 + 16 - first) == stored)
    except (OSError, struct.error):
        return False


def _data_crc_written(handle: IO[bytes], size: int) -> bool:
    """Whether the DataEnd record, found from the footer, holds a data section CRC (a hint:
    the walk checks the record itself when it gets there)."""
    try:
        footer_at = size - len(MAGIC) - 9 - _FOOTER_LENGTH
        handle.seek(footer_at)
        footer = handle.read(9 + _FOOTER_LENGTH)
        if struct.unpack_from("<BQ", footer) != (_FOOTER, _FOOTER_LENGTH):
            return False
        end_at = (struct.unpack_from("<Q", footer, 9)[0] or footer_at) - 13
        if end_at < len(MAGIC):
            return False
        handle.seek(end_at)
        opcode, length, crc = struct.unpack("<BQI", handle.read(13))
        return bool(opcode == _DATA_END and length == 4 and crc != 0)
    except (OSError, struct.error):
        return False


def _crc(handle: IO[bytes], n: int) -> int:
    """CRC-32 of the next ``n`` bytes of ``handle``, read in bounded blocks."""
    crc = 0
    while n > 0:
        block = handle.read(min(n, _BLOCK))
        if not block:
            break
        crc = zlib.crc32(block, crc)
        n -= len(block)
    return crc


class _Walker:
    def __init__(
        self, path: Path, handle: IO[bytes], take_chunk: Callable[[int, bytes], None] | None
    ) -> None:
        self.path = path
        self.handle = handle
        self.take_chunk = take_chunk
        handle.seek(0, 2)
        self.size = handle.tell()
        handle.seek(0)
        self.pos = 0
        self.crc = 0  # running CRC-32 of the data section, from the magic on
        self.chunks: dict[int, int] = {}  # chunk offset -> record length (opcode + length + body)
        # chunks whose CRC is left to the data section's: (offset, where its compressed records
        # are, their length, compression, uncompressed size and CRC)
        self.unchecked: list[tuple[int, int, int, bytes, int, int]] | None = None
        self.zstd: Any = None  # one decompression context for every chunk

    def damage(self, offset: int, detail: str) -> McapDamage:
        return McapDamage(self.path, offset, detail)

    def read(self, n: int, in_data: bool) -> bytes:
        data = self.handle.read(n)
        if len(data) != n:
            raise self.damage(self.pos, f"file ends {n - len(data)} bytes early (truncated?)")
        if in_data:
            self.crc = zlib.crc32(data, self.crc)
        self.pos += n
        return data

    def skip(self, n: int, in_data: bool) -> None:
        """Read past ``n`` bytes, adding them to the data CRC, in bounded blocks."""
        while n > 0:
            step = min(n, _BLOCK)
            self.read(step, in_data)
            n -= step

    def walk(self) -> None:
        try:
            self._walk()
        except McapDamage as damage:
            self._check_chunks(damage.offset)  # an earlier damaged chunk is named first
            raise

    def _walk(self) -> None:
        if self.size < 2 * len(MAGIC) or self.read(len(MAGIC), True) != MAGIC:
            raise self.damage(0, "not an MCAP file (no MCAP magic)")
        self.handle.seek(self.size - len(MAGIC))
        if self.handle.read(len(MAGIC)) != MAGIC:
            raise self.damage(
                self.size,
                "truncated or damaged MCAP file: no valid footer at the end (no closing magic); "
                "was the recording cut short? `mcap recover` can rebuild it",
            )
        if _data_crc_written(self.handle, self.size):
            self.unchecked = []
        self.handle.seek(self.pos)
        summary_start: int | None = None
        while True:
            start = self.pos
            if self.size - start < 9:
                raise self.damage(start, "file ends inside a record header (truncated?)")
            head = self.read(9, False)
            opcode, length = head[0], struct.unpack_from("<Q", head, 1)[0]
            left = self.size - self.pos
            if length > left:
                raise self.damage(
                    start,
                    f"record (opcode 0x{opcode:02x}) claims {length} bytes, only {left} remain "
                    "(truncated, or a damaged length field)",
                )
            if opcode == _DATA_END and summary_start is None:
                self._data_end(start, length)  # the data CRC covers every byte before it
                summary_start = self.pos
                continue
            if opcode == _FOOTER:
                self._check_chunks(start)  # (none left unless the file had no DataEnd record)
                self._footer(start, length)
                return
            if summary_start is None:
                self.crc = zlib.crc32(head, self.crc)
                self._data_record(start, opcode, length)
            else:
                self._summary_record(start, opcode, length)

    def _data_record(self, start: int, opcode: int, length: int) -> None:
        if opcode == _CHUNK:
            self._chunk(start, length)
        elif opcode == _ATTACHMENT:
            self._attachment(start, length)
        elif opcode == _MESSAGE and length < _MESSAGE_FIXED:
            raise self.damage(start, f"message record of {length} bytes, shorter than its fields")
        else:
            self.skip(length, True)

    def _data_end(self, start: int, length: int) -> None:
        expected_crc = self.crc
        body = self.read(length, False)
        if length < 4:
            raise self.damage(start, f"DataEnd record of {length} bytes, expected at least 4")
        stored = struct.unpack_from("<I", body)[0]
        if stored and stored != expected_crc:
            raise self.damage(
                start,
                f"data section CRC mismatch (stored {stored:#010x}, computed "
                f"{expected_crc:#010x}): bytes 0..{start} are damaged",
            )
        if not stored:  # no data section CRC after all: the chunks' own are the check
            self._check_chunks(start)
        self.unchecked = None  # the data section's CRC covered them

    def _check_chunks(self, before: int) -> None:
        """Check the CRCs left unchecked of the chunks at or before byte ``before``, in file
        order; raise at the first mismatch."""
        unchecked, self.unchecked = self.unchecked or [], None
        for start, at, size, compression, usize, ucrc in unchecked:
            if start > before:
                break
            self.handle.seek(at)
            data = self._decompress(start, compression, self.handle.read(size), usize)
            self._check_crc(start, data, ucrc, at, size)

    def _check_crc(self, start: int, data: bytes, ucrc: int, at: int, size: int) -> None:
        crc = zlib.crc32(data)
        if ucrc and crc != ucrc:
            raise self.damage(
                start,
                f"chunk CRC mismatch (stored {ucrc:#010x}, computed {crc:#010x}): the chunk's "
                f"data at bytes {at}..{at + size} is damaged",
            )

    def _chunk(self, start: int, length: int) -> None:
        body_start = self.pos
        body = self.read(length, True)
        self.chunks[start] = 9 + length
        try:
            _, _, usize, ucrc, clen = struct.unpack_from("<QQQII", body)
            compression = body[32 : 32 + clen]
            if len(compression) != clen:
                raise struct.error("compression name")
            (rlen,) = struct.unpack_from("<Q", body, 32 + clen)
        except struct.error:
            raise self.damage(
                start, f"chunk record of {length} bytes too short for its fields"
            ) from None
        data_at = 40 + clen
        if rlen != length - data_at:
            raise self.damage(
                start,
                f"chunk claims {rlen} bytes of records, its record holds {length - data_at} "
                "(damaged length field)",
            )
        if usize > MAX_CHUNK_BYTES:
            raise self.damage(
                start,
                f"chunk claims {usize} bytes uncompressed, above gridmap's limit of "
                f"{MAX_CHUNK_BYTES} bytes per chunk (MAX_CHUNK_BYTES)",
            )
        data = self._decompress(start, compression, memoryview(body)[data_at:], usize)
        if len(data) != usize:
            raise self.damage(
                start, f"chunk decompresses to {len(data)} bytes, its header says {usize}"
            )
        at, size = body_start + data_at, length - data_at
        if self.unchecked is None:
            self._check_crc(start, data, ucrc, at, size)
        elif ucrc:
            self.unchecked.append((start, at, size, bytes(compression), usize, ucrc))
        self._chunk_records(start, data)
        if self.take_chunk is not None:
            self.take_chunk(start, data)

    def _chunk_records(self, start: int, data: bytes) -> None:
        """The records inside a chunk: each fits, and is one a chunk may hold."""
        walk = compiled_walk()
        if (
            walk is not None
            and walk.mcap_records(data, _IN_CHUNK_BYTES, _MESSAGE, _MESSAGE_FIXED) < 0
        ):
            return  # sound: the Python walk below words the error when it is not
        for offset, opcode, rec_len, fits in _records(data):
            if not fits:
                raise self.damage(
                    start,
                    f"record at byte {offset} of the chunk's data claims {rec_len} bytes, more "
                    "than the chunk holds (damaged length field)",
                )
            if opcode not in _IN_CHUNK:
                raise self.damage(
                    start, f"record of opcode 0x{opcode:02x} inside a chunk (byte {offset} of it)"
                )
            if opcode == _MESSAGE and rec_len < _MESSAGE_FIXED:
                raise self.damage(
                    start, f"message record of {rec_len} bytes at byte {offset} of the chunk"
                )

    def _decompress(
        self, start: int, compression: bytes, data: bytes | memoryview, usize: int
    ) -> bytes:
        name = compression.decode("utf-8", errors="replace")
        try:
            if name == "":
                return bytes(data)
            if name == "zstd":
                import zstandard

                if self.zstd is None:
                    self.zstd = zstandard.ZstdDecompressor()
                result: bytes = self.zstd.decompress(data, max_output_size=usize)
                return result
            if name == "lz4":
                import lz4.frame

                return bytes(lz4.frame.decompress(data))
        except Exception as exc:  # each codec has its own error class; all mean damage here
            raise self.damage(
                start, f"{name} chunk does not decompress ({type(exc).__name__}: {exc})"
            ) from exc
        raise self.damage(start, f"chunk compression {name!r} unknown (known: zstd, lz4, none)")

    def _attachment(self, start: int, length: int) -> None:
        body = self.read(length, True)
        if length < 4:
            raise self.damage(start, f"attachment record of {length} bytes")
        stored = struct.unpack_from("<I", body, length - 4)[0]
        if stored and zlib.crc32(body[: length - 4]) != stored:
            raise self.damage(start, "attachment CRC mismatch: the attachment is damaged")

    def _summary_record(self, start: int, opcode: int, length: int) -> None:
        body = self.read(length, False)
        if opcode != _CHUNK_INDEX:
            return
        try:
            chunk_at, chunk_len = struct.unpack_from("<QQ", body, 16)
        except struct.error:
            raise self.damage(start, "chunk index record too short for its fields") from None
        if self.chunks.get(chunk_at) != chunk_len:
            raise self.damage(
                start,
                f"chunk index points at a chunk of {chunk_len} bytes at byte {chunk_at}; the "
                "data section has none there (damaged summary)",
            )

    def _footer(self, start: int, length: int) -> None:
        if length != _FOOTER_LENGTH or self.size - self.pos - length != len(MAGIC):
            raise self.damage(start, "footer record is not where the file ends (damaged)")
        body = self.read(length, False)
        summary_start, _, stored = struct.unpack("<QQI", body)
        if self.read(len(MAGIC), False) != MAGIC:
            raise self.damage(self.pos - len(MAGIC), "no MCAP magic at the end (truncated?)")
        if not stored:
            return
        first = summary_start or start
        if first > start:
            raise self.damage(start, f"footer's summary start {summary_start} is past the footer")
        self.handle.seek(first)
        crc = _crc(self.handle, start + 9 + 16 - first)
        if crc != stored:
            raise self.damage(
                first,
                f"summary CRC mismatch (stored {stored:#010x}, computed {crc:#010x}): the "
                f"summary at bytes {first}..{start} is damaged",
            )


def _records(data: bytes) -> Iterator[tuple[int, int, int, bool]]:
    """(offset, opcode, length, fits) of each record in a chunk's data; ``fits`` is False for a
    record whose header or length overruns the data (then the walk stops)."""
    pos = 0
    end = len(data)
    while pos < end:
        if end - pos < 9:
            yield pos, 0, end - pos, False
            return
        opcode = data[pos]
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        if length > end - pos - 9:
            yield pos, opcode, length, False
            return
        yield pos, opcode, length, True
        pos += 9 + length
