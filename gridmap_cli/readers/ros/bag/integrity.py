"""Check a ROS 1 bag's record structure before ``rosbags`` reads it, naming the byte offset of
the damage.

``rosbags`` reports a damaged bag as "Bag index looks damaged" or "Header could not be read",
without saying where. This walk reads the bag's records once (format 2.0: a 4-byte header
length, header fields ``name=value`` each with a 4-byte length, a 4-byte data length, the data)
and refuses at the first record whose lengths overrun the file or its chunk, whose ``op`` is
missing or unknown, whose chunk compression is unknown or whose uncompressed size lies, and
at a bag header whose index position, connection count or chunk count disagree with the
records found. Memory use is bounded by one chunk (:data:`MAX_CHUNK_BYTES`).
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import IO

from gridmap_cli.errors import DamagedAtError, InputFileError
from gridmap_cli.readers.ros.mcap.integrity import MAX_CHUNK_BYTES
from gridmap_cli.readers.ros.walk import compiled_walk

VERSION_LINE = b"#ROSBAG V2.0\n"
_MSG_DATA, _BAG_HEADER, _INDEX, _CHUNK, _CHUNK_INFO, _CONNECTION = 2, 3, 4, 5, 6, 7
_KNOWN_OPS = {_MSG_DATA, _BAG_HEADER, _INDEX, _CHUNK, _CHUNK_INFO, _CONNECTION}
_KNOWN_OPS_BYTES = bytes(sorted(_KNOWN_OPS))
_COMPRESSIONS = ("none", "bz2", "lz4")


class BagDamage(DamagedAtError):
    """``path: byte N: truncated or damaged ROS 1 bag: detail``."""

    def __init__(self, path: str | Path, offset: int, detail: str) -> None:
        super().__init__(path, offset, f"truncated or damaged ROS 1 bag: {detail}")


def verify_bag(path: Path) -> None:
    """Raise :class:`BagDamage` at the first structural damage in the ROS 1 bag ``path``;
    :class:`InputFileError` when it cannot be read."""
    try:
        with open(path, "rb") as handle:
            _walk(path, handle)
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from exc


def _fields(path: Path, at: int, header: bytes) -> dict[bytes, bytes]:
    fields: dict[bytes, bytes] = {}
    i = 0
    while i < len(header):
        if len(header) - i < 4:
            raise BagDamage(path, at, "record header ends inside a field length")
        (n,) = struct.unpack_from("<I", header, i)
        if n > len(header) - i - 4:
            raise BagDamage(
                path, at, f"record header field claims {n} bytes, the header holds {len(header)}"
            )
        name, sep, value = header[i + 4 : i + 4 + n].partition(b"=")
        if not sep:
            raise BagDamage(path, at, "record header field without '='")
        fields[name] = value
        i += 4 + n
    op = fields.get(b"op")
    if op is None or len(op) != 1 or op[0] not in _KNOWN_OPS:
        raise BagDamage(path, at, f"record of unknown op {op!r} (damaged header)")
    return fields


def _records(
    path: Path, data: bytes, base: int, where: str
) -> list[tuple[int, dict[bytes, bytes], int]]:
    """(offset, header fields, data length) of the records in ``data``, which starts at file
    offset ``base``; ``where`` names the container in errors."""
    out = []
    pos = 0
    while pos < len(data):
        at = base + pos
        if len(data) - pos < 8:
            raise BagDamage(path, at, f"{where} ends inside a record (truncated?)")
        (hlen,) = struct.unpack_from("<I", data, pos)
        if hlen > len(data) - pos - 8:
            raise BagDamage(
                path, at, f"record header claims {hlen} bytes, more than the {where} holds"
            )
        fields = _fields(path, at, data[pos + 4 : pos + 4 + hlen])
        (dlen,) = struct.unpack_from("<I", data, pos + 4 + hlen)
        if dlen > len(data) - pos - 8 - hlen:
            raise BagDamage(
                path, at, f"record data claims {dlen} bytes, more than the {where} holds"
            )
        out.append((at, fields, dlen))
        pos += 8 + hlen + dlen
    return out


def _u(fields: dict[bytes, bytes], name: bytes, fmt: str) -> int | None:
    value = fields.get(name)
    if value is None or len(value) != struct.calcsize(fmt):
        return None
    return int(struct.unpack(fmt, value)[0])


def _walk(path: Path, handle: IO[bytes]) -> None:
    handle.seek(0, 2)
    size = handle.tell()
    handle.seek(0)
    if handle.read(len(VERSION_LINE)) != VERSION_LINE:
        raise BagDamage(path, 0, "not a ROS 1 bag of format 2.0 (no '#ROSBAG V2.0' line)")
    pos = len(VERSION_LINE)
    starts: set[int] = set()
    chunks: set[int] = set()
    header: tuple[int, dict[bytes, bytes]] | None = None
    connections_after_index = 0
    index_pos: int | None = None
    while pos < size:
        at = pos
        head = handle.read(4)
        if len(head) < 4:
            raise BagDamage(path, at, "file ends inside a record (truncated?)")
        (hlen,) = struct.unpack("<I", head)
        if hlen > size - at - 8:
            raise BagDamage(
                path, at, f"record header claims {hlen} bytes, only {size - at - 4} remain "
                "(truncated, or a damaged length field)",
            )  # fmt: skip
        fields = _fields(path, at, handle.read(hlen))
        (dlen,) = struct.unpack("<I", handle.read(4))
        if dlen > size - at - 8 - hlen:
            raise BagDamage(
                path, at, f"record data claims {dlen} bytes, only {size - at - 8 - hlen} remain "
                "(truncated, or a damaged length field)",
            )  # fmt: skip
        op = fields[b"op"][0]
        starts.add(at)
        if op == _BAG_HEADER:
            header = (at, fields)
            index_pos = _u(fields, b"index_pos", "<Q")
            handle.seek(dlen, 1)
        elif op == _CHUNK:
            chunks.add(at)
            _chunk(path, at, fields, handle.read(dlen), at + 8 + hlen)
        else:
            if op == _CONNECTION and index_pos is not None and at >= index_pos:
                connections_after_index += 1
            if op == _CHUNK_INFO:
                chunk_pos = _u(fields, b"chunk_pos", "<Q")
                if chunk_pos not in chunks:
                    raise BagDamage(
                        path, at, f"chunk info points at byte {chunk_pos}, where no chunk starts"
                    )
            handle.seek(dlen, 1)
        pos = at + 8 + hlen + dlen
    if header is None:
        raise BagDamage(path, len(VERSION_LINE), "no bag header record")
    at, fields = header
    if index_pos is None or (index_pos != 0 and index_pos not in starts):
        raise BagDamage(
            path, at, f"bag header's index_pos {index_pos} is not where a record starts"
        )
    chunk_count = _u(fields, b"chunk_count", "<I")
    conn_count = _u(fields, b"conn_count", "<I")
    if index_pos and chunk_count != len(chunks):
        raise BagDamage(
            path, at, f"bag header counts {chunk_count} chunks, the file holds {len(chunks)}"
        )
    if index_pos and conn_count != connections_after_index:
        raise BagDamage(
            path, at, f"bag header counts {conn_count} connections, the index holds "
            f"{connections_after_index}",
        )  # fmt: skip


def _chunk(path: Path, at: int, fields: dict[bytes, bytes], data: bytes, data_at: int) -> None:
    compression = fields.get(b"compression", b"").decode("latin-1")
    usize = _u(fields, b"size", "<I")
    if compression not in _COMPRESSIONS:
        raise BagDamage(
            path, at, f"chunk compression {compression!r} unknown (known: none, bz2, lz4)"
        )
    if usize is None or usize > MAX_CHUNK_BYTES:
        raise BagDamage(path, at, f"chunk size {usize} missing or above MAX_CHUNK_BYTES")
    try:
        if compression == "bz2":
            import bz2

            raw = bz2.BZ2Decompressor().decompress(data, max_length=usize + 1)
        elif compression == "lz4":
            import lz4.frame

            raw = bytes(lz4.frame.decompress(data))
        else:
            raw = data
    except Exception as exc:  # each codec has its own error class: all mean damage here
        raise BagDamage(
            path, at, f"{compression} chunk does not decompress ({type(exc).__name__})"
        ) from exc
    if len(raw) != usize:
        raise BagDamage(
            path, at, f"chunk holds {len(raw)} bytes uncompressed, its header says {usize}"
        )
    base = data_at if compression == "none" else at
    walk = compiled_walk()
    if walk is not None:
        bad, others = walk.bag_records(raw, _KNOWN_OPS_BYTES, _MSG_DATA)
        if bad < 0:  # sound: only the records that are not messages are left to look at
            for pos in others:
                (hlen,) = struct.unpack_from("<I", raw, pos)
                _in_chunk(
                    path, base + pos, _fields(path, base + pos, raw[pos + 4 : pos + 4 + hlen])
                )
            return
    for inner_at, inner, _ in _records(path, raw, base, "chunk"):
        _in_chunk(path, inner_at, inner)


def _in_chunk(path: Path, at: int, fields: dict[bytes, bytes]) -> None:
    if fields[b"op"][0] not in (_MSG_DATA, _CONNECTION):
        raise BagDamage(path, at, "record of another kind inside a chunk")
