"""Bulk decoding of ROS messages from their raw bytes with numpy, column by column.

The MCAP and ROS 1 bag readers hand over the raw bytes of many messages of one channel at once:
one buffer, and each message's data offset and length in it. The layouts of the messages gridmap
reads most (``sensor_msgs/Range``, ``sensor_msgs/LaserScan``, ``nav_msgs/Odometry``,
``tf2_msgs/TFMessage``) are fixed up to their strings and arrays, so every field of every message
is one gather: the offset of the first string is known, and the offsets after it follow from
the string's length (read in bulk too). Two serialisations:

- ROS 2 CDR (little-endian, ``00 01`` encapsulation): primitives aligned to their size, counted
  from just after the 4-byte encapsulation header; strings carry their terminating NUL.
- ROS 1: no alignment, no NUL; the header starts with a ``uint32`` sequence number.

A decoder returns None when anything is not as expected (big-endian CDR, a length running past
its message, a NUL inside a string, a message of an unexpected size); the reader then decodes
that channel message by message with the ROS libraries, which raise the precise error. Values
are the ones the libraries give: float32 fields widened to float64, stamps as integers.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

IntArray = npt.NDArray[np.int64]
Arr = npt.NDArray[Any]

#: The message types decoded in bulk, by folded type name.
TF_TYPES = frozenset({"tf2_msgs/TFMessage", "tf/tfMessage"})  # one layout, two names
BULK_TYPES = frozenset(
    {"sensor_msgs/Range", "sensor_msgs/LaserScan", "nav_msgs/Odometry", *TF_TYPES}
)


class Layout(Exception):
    """The bytes are not laid out as the bulk decoder expects (decode message by message)."""


@dataclass
class Raw:
    """Raw messages of one channel: ``buf`` (bytes, uint8), each message's data ``offset`` and
    ``length`` in it (int64, (N,)), its log time (ns) and a file-order position (int64, (N,))."""

    buf: npt.NDArray[np.uint8]
    offset: IntArray
    length: IntArray
    log_ns: IntArray
    pos: IntArray


@dataclass
class Columns:
    """Decoded messages of one channel, one row per message (per transform for TF).

    ``arrays`` are row-aligned; a string column holds indexes into ``names[column]``. Laser
    ranges are ragged: ``ranges`` holds them flat, row ``i`` has ``arrays["count"][i]``.
    """

    arrays: dict[str, Arr]
    names: dict[str, list[str]] = field(default_factory=dict)
    ranges: npt.NDArray[np.float32] | None = None

    def __len__(self) -> int:
        return len(self.arrays["log_ns"])

    def name_column(self, column: str) -> list[str]:
        """The column as a list of strings (for small columns and error messages)."""
        names = self.names[column]
        return [names[i] for i in self.arrays[column].tolist()]


def words(buf: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint64]:
    """The 8 bytes from each place of ``buf`` as a little-endian uint64, shape
    (len(buf) - 7,): a view, so ``words(buf)[at]`` gathers 8 bytes a place in one step."""
    return field_view(buf, np.dtype("<u8"))


def field_view(buf: npt.NDArray[np.uint8], dtype: np.dtype[Any]) -> Arr:
    """``buf`` read as ``dtype`` from each byte on, shape (len(buf) - itemsize + 1,): a view
    with a stride of one byte, so ``field_view(buf, dtype)[at]`` gathers a field at each of the
    (unaligned) offsets ``at`` in one step."""
    size = dtype.itemsize
    return np.ndarray((max(len(buf) - size + 1, 0),), dtype=dtype, buffer=buf, strides=(1,))


def gather_bytes(buf: npt.NDArray[np.uint8], at: IntArray, width: int) -> Arr:
    """The ``width`` bytes from each of the offsets ``at``, one row (a void scalar) each: one
    gather however many fields the bytes hold (:func:`column` reads them)."""
    return field_view(buf, np.dtype((np.void, width)))[at]


def column(block: Arr, offset: int, dtype: np.dtype[Any]) -> Arr:
    """The ``dtype`` field at byte ``offset`` of each row of ``block`` (from
    :func:`gather_bytes`): a view, no copy."""
    if len(block) == 0:
        return np.zeros(0, dtype=dtype)
    width = block.dtype.itemsize
    return np.ndarray((len(block),), dtype=dtype, buffer=block, offset=offset, strides=(width,))


def concat(parts: list[Columns]) -> Columns:
    """Rows of several Columns, in log-time order (ties in file order, then transform order)."""
    if len(parts) == 1:
        out = parts[0]
    else:
        arrays = {k: np.concatenate([p.arrays[k] for p in parts]) for k in parts[0].arrays}
        names: dict[str, list[str]] = {}
        for column in parts[0].names:
            merged: dict[str, int] = {}
            pieces = []
            for p in parts:
                remap = np.array(
                    [merged.setdefault(n, len(merged)) for n in p.names[column]], dtype=np.int64
                )
                pieces.append(remap[p.arrays[column]] if len(remap) else p.arrays[column])
            arrays[column] = np.concatenate(pieces)
            names[column] = list(merged)
        ranges = None
        if parts[0].ranges is not None:
            ranges = np.concatenate([p.ranges for p in parts if p.ranges is not None])
        out = Columns(arrays, names, ranges)
    keys = [out.arrays["pos"], out.arrays["log_ns"]]
    if "sub" in out.arrays:
        keys.insert(0, out.arrays["sub"])
    order = lexsort_order(keys)
    return out if order is None else take(out, order)


def lexsort_order(keys: Sequence[Arr]) -> npt.NDArray[np.intp] | None:
    """``np.lexsort(keys)`` (the last key sorts first), or None when the rows are in that order
    already: rows read from a recording mostly are, and one pass finds it where sorting takes
    many."""
    undecided = np.ones(max(len(keys[-1]) - 1, 0), dtype=bool)  # pairs tied so far
    for key in reversed(keys):
        ahead, behind = key[:-1], key[1:]
        if np.any(undecided & (ahead > behind)):
            return np.lexsort(keys)
        undecided &= ahead == behind
        if not undecided.any():
            break
    return None  # ties on every key stay as they are, as a stable sort leaves them


def take(cols: Columns, rows: npt.NDArray[np.intp]) -> Columns:
    """The given rows, in the given order."""
    arrays = {k: v[rows] for k, v in cols.arrays.items()}
    ranges = None
    if cols.ranges is not None:
        count = cols.arrays["count"]
        start = np.concatenate(([0], np.cumsum(count)[:-1])).astype(np.int64)
        ranges = cols.ranges[_ragged_index(start[rows], count[rows])]
    return Columns(arrays, cols.names, ranges)


def _ragged_index(start: IntArray, count: Arr) -> IntArray:
    """Flat indexes of the runs [start[i], start[i] + count[i])."""
    count = count.astype(np.int64)
    total = int(count.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    run_start = np.concatenate(([0], np.cumsum(count)[:-1]))
    return np.repeat(start - run_start, count) + np.arange(total, dtype=np.int64)


# ---------------------------------------------------------------------- byte access
class _Reader:
    """Gathers little-endian fields at per-message offsets, checking each stays inside its
    message."""

    def __init__(self, raw: Raw, cdr: bool) -> None:
        self.buf = raw.buf
        self.raw = raw
        self.cdr = cdr
        self.views: dict[np.dtype[Any], Arr] = {}
        self.end = raw.offset + raw.length
        # each message's first 16 bytes in one gather: (CDR's encapsulation, or ROS 1's
        # sequence number) and a header's stamp and frame id length, or a TF list's length
        self.head: Arr | None = None
        if len(raw.length) and int(raw.length.min()) >= _HEAD_BYTES:
            self.head = gather_bytes(self.buf, raw.offset, _HEAD_BYTES)
        if cdr:
            if np.any(raw.length < 4):
                raise Layout("short CDR message")
            kind = self.first(0, np.dtype("<u2"))
            if np.any(kind != 0x0100):  # CDR_LE: 00 01; anything else message by message
                raise Layout("not little-endian CDR")
            self.origin = raw.offset + 4
        else:
            self.origin = raw.offset

    def first(self, at: int, dtype: np.dtype[Any]) -> Arr:
        """The field at byte ``at`` of each message (inside its first 16 bytes)."""
        if self.head is None:
            return self.get(self.raw.offset + at, dtype)
        return column(self.head, at, dtype)

    def get(self, at: IntArray, dtype: np.dtype[Any]) -> Arr:
        size = dtype.itemsize
        if np.any(at + size > self.end) or np.any(at < self.raw.offset):
            raise Layout("field past the end of its message")
        return self.gather(at, dtype)

    def run(self, at: IntArray, dtype: np.dtype[Any], n: int) -> list[Arr]:
        """``n`` fields of ``dtype`` one after another from ``at``: one gather of the run
        (the bytes of a message are fetched once, not once a field)."""
        size = dtype.itemsize
        if np.any(at + n * size > self.end) or np.any(at < self.raw.offset):
            raise Layout("field past the end of its message")
        block = gather_bytes(self.buf, at, n * size)
        return [column(block, i * size, dtype) for i in range(n)]

    def gather(self, at: IntArray, dtype: np.dtype[Any]) -> Arr:
        """The fields at ``at``, unchecked (the caller has checked they are inside)."""
        view = self.views.get(dtype)
        if view is None:
            view = self.views[dtype] = field_view(self.buf, dtype)
        out: Arr = view[at]
        return out

    def align(self, at: IntArray, size: int) -> IntArray:
        """``at`` moved to the next multiple of ``size`` from the CDR origin (ROS 1: as is)."""
        if not self.cdr:
            return at
        rel = at - self.origin
        return self.origin + (rel + size - 1) // size * size

    def string(
        self, at: IntArray, length: Arr | None = None
    ) -> tuple[IntArray, list[str], IntArray]:
        """A string at ``at`` (aligned here; its ``length`` field read already or not):
        (index into the names, names, offset after it)."""
        at = self.align(at, 4)
        n = (self.get(at, np.dtype("<u4")) if length is None else length).astype(np.int64)
        chars = at + 4
        after = chars + n
        if np.any(after > self.end):
            raise Layout("string past the end of its message")
        text = n - 1 if self.cdr else n
        if self.cdr and (np.any(n < 1) or np.any(self.buf[np.maximum(after - 1, 0)] != 0)):
            raise Layout("CDR string without its NUL")
        index, names = _unique_strings(self.buf, chars, text)
        return index, names, after


def _unique_strings(
    buf: npt.NDArray[np.uint8], start: IntArray, length: IntArray
) -> tuple[IntArray, list[str]]:
    """The strings buf[start:start+length] as indexes into their distinct values (first seen
    first)."""
    if len(start) == 0:
        return np.zeros(0, dtype=np.int64), []
    width = int(length.max())
    if width == 0:
        return np.zeros(len(start), dtype=np.int64), [""]
    # each string as whole 8-byte words, padded with NULs (a string holds none, so no two
    # collide): a frame id of up to 8 bytes is then one integer, which sorts many times faster
    # than bytes do
    n_words = -(-width // 8)
    word = words(buf)
    if len(word) == 0:
        return _unique_rows(buf, start, length, _string_bytes(buf, start, length, n_words))
    last = len(word) - 1
    keys = np.empty((len(start), n_words), dtype=np.uint64)
    for j in range(n_words):
        at = start + 8 * j
        mask = _MASK[np.clip(length - 8 * j, 0, 8)]
        if int(at.max()) <= last:
            value = word[at] & mask
        else:
            # a word that would run past the buffer is read from 8 bytes before its end,
            # shifted (the string ends inside the buffer: a word starting at its end keeps
            # no byte)
            inside = np.minimum(at, last)
            shift = (8 * (at - inside)).astype(np.uint64)
            value = (word[inside] >> np.minimum(shift, np.uint64(56))) & mask
        # a NUL among the string's bytes: the padding set to 0xff, any zero byte is one
        padded = value | ~mask
        if np.any((padded - _ONES) & ~padded & _HIGHS):
            raise Layout("NUL inside a string")
        keys[:, j] = value
    return _unique_rows(buf, start, length, keys)


#: The low ``k`` bytes of a word, for k = 0..8.
_MASK = np.array([(1 << (8 * k)) - 1 for k in range(9)], dtype=np.uint64)
_ONES = np.uint64(0x0101010101010101)
_HIGHS = np.uint64(0x8080808080808080)


def _string_bytes(
    buf: npt.NDArray[np.uint8], start: IntArray, length: IntArray, n_words: int
) -> npt.NDArray[np.uint64]:
    """The strings' bytes padded with NULs to ``n_words`` words each, shape (N, n_words)."""
    cols = np.arange(8 * n_words, dtype=np.int64)
    inside = cols < length[:, None]
    mat = np.where(inside, buf[np.where(inside, start[:, None] + cols, 0)], 0).astype(np.uint8)
    if np.any(inside & (mat == 0)):
        raise Layout("NUL inside a string")
    return np.ascontiguousarray(mat).view("<u8")


def _unique_rows(
    buf: npt.NDArray[np.uint8], start: IntArray, length: IntArray, keys: npt.NDArray[np.uint64]
) -> tuple[IntArray, list[str]]:
    """Indexes into the distinct rows of ``keys`` (N, words), first seen first, and the
    strings they stand for."""
    n = len(keys)
    inverse, count = _dense_rank(keys[:, 0])
    for j in range(1, keys.shape[1]):  # longer strings: (rank so far, next word) ranked again
        word, word_count = _dense_rank(keys[:, j])
        inverse, count = _dense_rank(inverse * word_count + word)
    first = np.full(count, n, dtype=np.int64)
    np.minimum.at(first, inverse, np.arange(n, dtype=np.int64))
    by_first = np.argsort(first, kind="stable")
    rank = np.empty_like(by_first)
    rank[by_first] = np.arange(count)
    names = []
    for i in first[by_first].tolist():
        try:
            names.append(bytes(buf[start[i] : start[i] + length[i]]).decode("utf-8"))
        except UnicodeDecodeError as exc:
            raise Layout("a string that is not UTF-8") from exc
    return rank[inverse], names


def _dense_rank(values: Arr) -> tuple[IntArray, int]:
    """Each value's index among the distinct values (sorted), and how many there are: a sort
    and a binary search, several times faster than ``np.unique``'s inverse."""
    ordered = np.sort(values)
    distinct = ordered[np.concatenate(([True], ordered[1:] != ordered[:-1]))]
    return np.searchsorted(distinct, values).astype(np.int64), len(distinct)


_U4 = np.dtype("<u4")
_HEAD_BYTES = 16
_I4 = np.dtype("<i4")
_F4 = np.dtype("<f4")
_F8 = np.dtype("<f8")


def _header(r: _Reader) -> tuple[IntArray, IntArray, list[str], IntArray]:
    """std_msgs/Header: (stamp ns, frame index, frame names, offset after it)."""
    at = r.origin if r.cdr else r.origin + 4  # ROS 1: uint32 seq first
    # (CDR's 4-byte encapsulation or ROS 1's seq, then stamp and frame id length: byte 4 on)
    sec, nsec, length = (r.first(k, _U4) for k in (4, 8, 12))
    if r.cdr:
        sec = sec.view(_I4)
    frame, names, after = r.string(at + 8, length)
    return sec.astype(np.int64) * 1_000_000_000 + nsec, frame, names, after


def _base(raw: Raw) -> dict[str, Arr]:
    return {"log_ns": raw.log_ns, "pos": raw.pos}


def _floats(r: _Reader, at: IntArray, dtype: np.dtype[Any], n: int) -> list[Arr]:
    return r.run(r.align(at, dtype.itemsize), dtype, n)


def decode_range(raw: Raw, cdr: bool) -> Columns:
    """sensor_msgs/Range: stamp, frame, field_of_view, min_range, max_range, range (float32)."""
    r = _Reader(raw, cdr)
    stamp, frame, names, at = _header(r)
    fov, rmin, rmax, rng = _floats(r, at + 1, _F4, 4)  # after the uint8 radiation_type
    # ROS 2 Jazzy and later add ``float32 variance`` at the end
    _exact_end(r, r.align(at + 1, 4) + 16, extra=4)
    arrays = {**_base(raw), "stamp_ns": stamp, "frame": frame, "fov": fov, "min": rmin}
    arrays.update({"max": rmax, "range": rng})
    return Columns(arrays, {"frame": names})


def decode_odometry(raw: Raw, cdr: bool) -> Columns:
    """nav_msgs/Odometry: stamp, frame, child frame, position x y, orientation (qx qy qz qw)."""
    r = _Reader(raw, cdr)
    stamp, frame, names, at = _header(r)
    child, child_names, at = r.string(at)
    x, y, _z, qx, qy, qz, qw = _floats(r, at, _F8, 7)
    # 36 covariance doubles, then the twist's 6 and its 36
    _exact_end(r, r.align(at, 8) + 8 * (7 + 36 + 6 + 36))
    arrays = {**_base(raw), "stamp_ns": stamp, "frame": frame, "child": child, "x": x, "y": y}
    arrays.update({"qx": qx, "qy": qy, "qz": qz, "qw": qw})
    return Columns(arrays, {"frame": names, "child": child_names})


def decode_tf(raw: Raw, cdr: bool) -> Columns:
    """tf2_msgs/TFMessage: one row per transform (``sub`` its place in the message): stamp,
    parent and child frame, translation and rotation (float64)."""
    r = _Reader(raw, cdr)
    count = r.get(r.origin, _U4).astype(np.int64)
    at = r.origin + 4
    parts: list[Columns] = []
    todo = np.arange(len(count))
    j = 0
    while True:
        todo = todo[count[todo] > j]
        if len(todo) == 0:
            break
        sub = _Reader.__new__(_Reader)
        sub.buf, sub.cdr, sub.views, sub.head = r.buf, cdr, r.views, None
        sub.raw = Raw(r.buf, raw.offset[todo], raw.length[todo], raw.log_ns[todo], raw.pos[todo])
        sub.end, sub.origin = r.end[todo], r.origin[todo]
        here = at[todo]
        h = sub.align(here, 4)
        sec = sub.get(h, _I4 if cdr else _U4).astype(np.int64)
        if not cdr:  # ROS 1 header: seq, then the stamp
            sec = sub.get(h + 4, _U4).astype(np.int64)
            h = h + 4
        nsec = sub.get(h + 4, _U4).astype(np.int64)
        parent, parent_names, after = sub.string(h + 8)
        child, child_names, after = sub.string(after)
        values = _floats(sub, after, _F8, 7)
        at[todo] = sub.align(after, 8) + 56
        arrays = {
            "log_ns": sub.raw.log_ns,
            "pos": sub.raw.pos,
            "sub": np.full(len(todo), j, dtype=np.int64),
            "stamp_ns": sec * 1_000_000_000 + nsec,
            "parent": parent,
            "child": child,
        }
        arrays.update(dict(zip(("tx", "ty", "tz", "qx", "qy", "qz", "qw"), values, strict=True)))
        parts.append(Columns(arrays, {"parent": parent_names, "child": child_names}))
        j += 1
    _exact_end(r, at)
    if not parts:
        empty: dict[str, Arr] = {
            k: np.zeros(0, dtype=np.int64) for k in ("log_ns", "pos", "sub", "stamp_ns")
        }
        empty.update({"parent": np.zeros(0, dtype=np.int64), "child": np.zeros(0, np.int64)})
        empty.update({k: np.zeros(0) for k in ("tx", "ty", "tz", "qx", "qy", "qz", "qw")})
        return Columns(empty, {"parent": [], "child": []})
    return concat(parts)


def decode_scan(raw: Raw, cdr: bool) -> Columns:
    """sensor_msgs/LaserScan: stamp, frame, angle_min, angle_max, angle_increment, range_min,
    range_max (float32) and the ranges (float32, ragged)."""
    r = _Reader(raw, cdr)
    stamp, frame, names, at = _header(r)
    amin, amax, ainc, _tinc, _scan_t, rmin, rmax = _floats(r, at, _F4, 7)
    at = r.align(at, 4) + 28
    count = r.get(at, _U4).astype(np.int64)
    first = at + 4
    after = first + 4 * count
    if np.any(after > r.end):
        raise Layout("ranges past the end of the message")
    n_int = r.get(after, _U4).astype(np.int64)
    _exact_end(r, after + 4 + 4 * n_int)
    beam = _ragged_index(np.zeros(len(count), dtype=np.int64), count)
    flat = np.repeat(first, count) + 4 * beam  # byte offset of each range
    ranges = r.gather(flat, _F4)
    arrays = {**_base(raw), "stamp_ns": stamp, "frame": frame, "angle_min": amin}
    arrays.update({"angle_max": amax, "angle_increment": ainc, "range_min": rmin})
    arrays.update({"range_max": rmax, "count": count})
    return Columns(arrays, {"frame": names}, ranges)


def _exact_end(r: _Reader, end: IntArray, extra: int = 0) -> None:
    """Each message ends where its layout says (CDR may pad to 4 bytes), or ``extra`` bytes
    later (a field newer distributions append)."""
    slack = r.end - end
    slack = np.where(slack >= extra, slack - extra, slack) if extra else slack
    if np.any(slack < 0) or np.any(slack >= (4 if r.cdr else 1)):
        raise Layout("message size differs from its layout")


DECODERS = {
    "sensor_msgs/Range": decode_range,
    "sensor_msgs/LaserScan": decode_scan,
    "nav_msgs/Odometry": decode_odometry,
    "tf2_msgs/TFMessage": decode_tf,
    "tf/tfMessage": decode_tf,
}


def decode(type_name: str, raw: Raw, cdr: bool) -> Columns:
    """Decode raw messages of ``type_name`` (one of :data:`BULK_TYPES`); raises
    :class:`Layout` when they are not as expected."""
    return DECODERS[type_name](raw, cdr)
