"""Bulk decoding of gridmap's own JSON channels (``gridmap.Pose2D``, ``gridmap.RangeReading``).

The MCAP reader hands over the raw bytes of many messages of one channel at once
(:class:`~gridmap_cli.readers.ros.bulk.Raw`). Two ways, the first that applies:

- the compact layout gridmap writes (``schemas/mcap-log.md``; ``json.dumps`` with
  ``separators=(",", ":")``): the keys in the schema's order, integer stamps of up to 9 digits
  a field, ASCII names without escapes, numbers of up to 32 characters. Read with numpy like
  the ROS layouts: each literal text is compared at every message's offset, a field ends at
  the next ``"``, ``,`` or ``}``, numbers are checked against JSON's grammar by a small
  automaton (NaN and Infinity as Python's ``json`` writes them) and read by ``float`` of the
  same text, as ``json`` reads them. Where the compiled walks are built
  (:mod:`~gridmap_cli.readers.ros.walk`), a C matcher (``_cjson.c``) does the same message by
  message, about ten times faster; it takes only what the numpy matcher takes, and where it
  does not take every message of a chunk, the numpy matcher, the reference, reads the chunk.
- any other JSON object: one ``json`` decoder parses each message from its own first byte in a
  tight loop, and a message must end exactly where the next begins.

The values are then turned into columns (:class:`~gridmap_cli.readers.ros.bulk.Columns`) as
:mod:`~gridmap_cli.readers.ros.bulk` gives them for ROS messages. Anything else (text that is
not ASCII, a string where a number belongs, a malformed message) raises
:class:`~gridmap_cli.readers.ros.bulk.Layout`, and the channel is read message by message,
which accepts what it accepts and names a bad message.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.readers.ros.bulk import Arr, Columns, Layout, Raw, _ragged_index, words
from gridmap_cli.readers.ros.walk import compiled_walk

#: gridmap's JSON message types decoded in bulk.
JSON_TYPES = frozenset({"gridmap.Pose2D", "gridmap.RangeReading"})

_DECODER = json.JSONDecoder()
_NUMBER = (float, int)

# ---------------------------------------------------------------------- gridmap's own layout
#: the compact layout gridmap writes, literal texts and fields in turn; a field ends at the
#: first byte of the literal after it
_COMPACT: dict[str, tuple[bytes | str, ...]] = {
    "gridmap.Pose2D": (
        b'{"timestamp":{"sec":',
        "int",
        b',"nsec":',
        "int",
        b'},"frame_id":"',
        "str",
        b'","child_frame_id":"',
        "str",
        b'","x":',
        "num",
        b',"y":',
        "num",
        b',"theta":',
        "num",
        b"}",
    ),
    "gridmap.RangeReading": (
        b'{"timestamp":{"sec":',
        "int",
        b',"nsec":',
        "int",
        b'},"sensor":"',
        "str",
        b'","range":',
        "num",
        b"}",
    ),
}
#: longest field: stamps of up to 9 digits (sec * 1e9 + nsec fits in int64); numbers of up to
#: 32 characters (an integer a double holds); names of up to 64 (longer: the general path)
_WIDTH = {"int": 10, "num": 32, "str": 64}
_SPECIAL = [b"NaN", b"Infinity", b"-Infinity"]


def _number_automaton(fraction: bool) -> npt.NDArray[np.int64]:
    """A JSON number (``fraction``: with fraction and exponent) read byte by byte, then a NUL:
    table[state, byte] -> state; state 9 is a whole number, 10 a bad one."""
    table = np.full((11, 256), 10, dtype=np.int64)
    digits, ones = np.arange(48, 58), np.arange(49, 58)
    table[0, 45], table[0, 48], table[0, ones] = 1, 2, 3  # start: - 0 1-9
    table[1, 48], table[1, ones] = 2, 3  # after -
    table[3, digits] = 3
    if fraction:
        for state in (2, 3):
            table[state, 46] = 4  # .
            table[state, [69, 101]] = 6  # e E
        table[4, digits] = table[5, digits] = 5
        table[5, [69, 101]] = 6
        table[6, [43, 45]] = 7
        table[6, digits] = table[7, digits] = table[8, digits] = 8
    for state in (2, 3, 5, 8, 9):
        table[state, 0] = 9  # the end (NUL padding)
    return table


_AUTOMATA = {"int": _number_automaton(False), "num": _number_automaton(True)}
_NAME_BYTES = np.zeros(256, dtype=bool)
_NAME_BYTES[0x20:0x7F] = True
_NAME_BYTES[[0x22, 0x5C]] = False  # printable ASCII but " and \\ (no escapes)
#: bytes looked at first for a field's end (a multiple of 8); the longest fields take a second
#: look of the field's whole width
_FIRST_LOOK = {"int": 16, "num": 24, "str": 16}
_PAD = 80  # zero bytes after a chunk's copy, so a window of a field never runs past it
_last: list[tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint64]]] = []  # the last chunk's


def _chunk(buf: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint64]:
    """The 8 bytes from each place of the chunk padded with zeros (once per chunk: the reader
    decodes its channels one after the other)."""
    if not _last or _last[0][0] is not buf:
        _last[:] = [(buf, words(np.concatenate((buf, np.zeros(_PAD, dtype=np.uint8)))))]
    return _last[0][1]


def _literal(text: bytes) -> list[tuple[int, int, int]]:
    """``text`` as (place, 8 bytes, mask) words to compare with :func:`words` at a message's
    place: whole words, the last one overlapping the one before (or masked, for a short text)."""
    if len(text) < 8:
        pad = text.ljust(8, b"\0")
        mask = (b"\xff" * len(text)).ljust(8, b"\0")
        return [(0, int.from_bytes(pad, "little"), int.from_bytes(mask, "little"))]
    places = [*range(0, len(text) - 7, 8), len(text) - 8]
    full = (1 << 64) - 1
    return [(i, int.from_bytes(text[i : i + 8], "little"), full) for i in dict.fromkeys(places)]


_LITERALS = {
    name: [_literal(p) if isinstance(p, bytes) else [] for p in parts]
    for name, parts in _COMPACT.items()
}


def _window(at: Arr, word: npt.NDArray[np.uint64], width: int) -> npt.NDArray[np.uint8]:
    """The ``width`` bytes (a multiple of 8) from each place ``at``, shape (N, width)."""
    gathered = np.stack([word[at + i] for i in range(0, width, 8)], axis=1)
    return gathered.view(np.uint8)


def _stop(window: npt.NDArray[np.uint8]) -> Arr:
    """The place of the first " , } or NUL in each row of ``window`` (-1 if none), (N,). A NUL
    ends a field so that the text after it must be the next literal: the automaton would take
    it for the zeros after a number."""
    stop = (window == 0x22) | (window == 0x2C) | (window == 0x7D) | (window == 0)
    first = stop.argmax(axis=1)
    return np.where(stop[np.arange(len(first)), first], first, -1)


#: the layouts as the compiled matcher takes them: literal texts, and fields as 0 (integer),
#: 1 (number) or 2 (name)
_C_LAYOUT = {
    name: tuple(p if isinstance(p, bytes) else ("int", "num", "str").index(p) for p in parts)
    for name, parts in _COMPACT.items()
}


def _compact(type_name: str, raw: Raw) -> Columns | None:
    """The messages as columns, if every one has gridmap's compact layout: matched by the
    compiled matcher when it is built; where it does not take every message, by the numpy
    matcher, the reference."""
    walk = compiled_walk()
    if walk is not None:
        cols = _compact_compiled(walk, type_name, raw)
        if cols is not None:
            return cols
    return _compact_numpy(type_name, raw)


def _compact_compiled(walk: Any, type_name: str, raw: Raw) -> Columns | None:
    """The messages as columns, if the compiled matcher (``_cjson.c``) takes every one."""
    n = len(raw.offset)
    kinds = [p for p in _COMPACT[type_name] if isinstance(p, str)]
    outs = tuple(np.empty(n, dtype=np.float64 if k == "num" else np.int64) for k in kinds)
    ok = np.empty(n, dtype=np.uint8)
    offset = np.ascontiguousarray(raw.offset, dtype=np.int64)
    length = np.ascontiguousarray(raw.length, dtype=np.int64)
    names = walk.json_compact(raw.buf, offset, length, _C_LAYOUT[type_name], outs, ok)
    if not ok.all():
        return None
    values = [out if name is None else (out, name) for out, name in zip(outs, names, strict=True)]
    return _assemble(type_name, raw, values)


def _compact_numpy(type_name: str, raw: Raw) -> Columns | None:
    """The messages as columns, if every one has gridmap's compact layout (numpy)."""
    end = raw.offset + raw.length
    word = _chunk(raw.buf)
    at = raw.offset
    fields: list[tuple[str, npt.NDArray[np.uint8], Arr]] = []
    parts = _COMPACT[type_name]
    for i, part in enumerate(parts):
        if isinstance(part, bytes):
            k = len(part)
            if np.any(at + k > end):
                return None
            for place, value, mask in _LITERALS[type_name][i]:
                got = word[at + place]
                if mask != (1 << 64) - 1:
                    got = got & np.uint64(mask)
                if np.any(got != np.uint64(value)):
                    return None
            at = at + k
            continue
        # the field ends at the first " , or } within its longest width (the byte after it
        # included): a look at the first bytes, then at all of them if some field is longer
        limit = _WIDTH[part]
        window = _window(at, word, _FIRST_LOOK[part])
        length = _stop(window)
        if np.any(length < 0):
            window = _window(at, word, (limit + 8) // 8 * 8)
            length = _stop(window[:, : limit + 1])
            if np.any(length < 0):
                return None
        nxt = parts[i + 1]
        assert isinstance(nxt, bytes)
        if np.any(window[np.arange(len(at)), length] != nxt[0]):
            return None
        width = max(int(length.max()), 1)
        inside = np.arange(width, dtype=np.int64) < length[:, None]
        fields.append((part, np.where(inside, window[:, :width], np.uint8(0)), length))
        at = at + length
    if np.any(at != end):
        return None
    return _compact_columns(type_name, raw, fields)


def _compact_columns(
    type_name: str, raw: Raw, fields: list[tuple[str, npt.NDArray[np.uint8], Arr]]
) -> Columns | None:
    values: list[Any] = []
    for kind, matrix, length in fields:
        n, width = matrix.shape
        if kind == "str":
            inside = np.arange(width) < length[:, None]
            if np.any(inside & ~_NAME_BYTES[matrix]):
                return None
            if width <= 8:  # most names: one uint64 a name, which sorts fast
                wide = np.zeros((n, 8), dtype=np.uint8)
                wide[:, :width] = matrix
                rows: Arr = wide.view(np.uint64).reshape(-1)
            else:
                rows = np.ascontiguousarray(matrix).view(np.dtype((np.void, width))).reshape(-1)
            _, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
            by_first = np.argsort(first, kind="stable")
            rank = np.empty_like(by_first)
            rank[by_first] = np.arange(len(by_first))
            names = [matrix[i, : length[i]].tobytes().decode("ascii") for i in first[by_first]]
            values.append((rank[inverse.reshape(-1)].astype(np.int64), names))
            continue
        state = np.zeros(n, dtype=np.int64)
        automaton = _AUTOMATA[kind].reshape(-1)
        for column in np.ascontiguousarray(matrix.T):
            state = automaton[state * 256 + column]
        state = automaton[state * 256]  # then the end
        texts = matrix.view(f"S{width}").reshape(-1)
        ok = state == 9
        if kind == "num" and not ok.all():
            odd = ~ok
            ok[odd] = np.isin(texts[odd], _SPECIAL)
        if not ok.all():
            return None
        if kind == "int":
            if np.any((length > 9) & (matrix[:, 0] != 45)):  # 9 digits and a sign at most
                return None
            digits = matrix.astype(np.int64) - 48
            value = np.zeros(n, dtype=np.int64)
            for column, digit in zip(matrix.T, digits.T, strict=True):
                value = np.where(column >= 48, value * 10 + digit, value)  # not - or the end
            values.append(np.where(matrix[:, 0] == 45, -value, value))
        else:
            # numpy reads bytes as ``float`` does (Python's own parser), as ``json`` does; but
            # ``json`` reads -0 as the integer 0, which is +0.0 as a float
            number = texts.astype(np.float64)
            values.append(np.where(texts == b"-0", 0.0, number))
    return _assemble(type_name, raw, values)


def _assemble(type_name: str, raw: Raw, values: list[Any]) -> Columns:
    """Columns of the fields' values in the layout's order: integers (int64, (N,)), numbers
    (float64, (N,)), names (indexes (int64, (N,)) and the distinct names, first seen first)."""
    arrays: dict[str, Arr] = {"log_ns": raw.log_ns, "pos": raw.pos}
    arrays["stamp_ns"] = values[0] * 1_000_000_000 + values[1]
    if type_name == "gridmap.Pose2D":
        arrays["child"], child_names = values[3]
        arrays.update(dict(zip(("x", "y", "theta"), values[4:], strict=True)))
        return Columns(arrays, {"child": child_names})
    arrays["sensor"], sensor_names = values[2]
    arrays["range"] = values[3]
    return Columns(arrays, {"sensor": sensor_names})


def decode(type_name: str, raw: Raw) -> Columns:
    """Decode raw JSON messages of ``type_name`` (one of :data:`JSON_TYPES`)."""
    cols = _compact(type_name, raw)
    if cols is not None:
        return cols
    msgs = _parse(raw)
    if type_name == "gridmap.Pose2D":
        return _pose2d(raw, msgs)
    return _reading(raw, msgs)


def _parse(raw: Raw) -> list[dict[str, Any]]:
    """Each message's JSON object, parsed from its own bytes."""
    length = raw.length
    joined = raw.buf[_ragged_index(raw.offset, length)].tobytes()
    try:
        text = joined.decode("ascii")
    except UnicodeDecodeError as exc:
        raise Layout("JSON text that is not ASCII") from exc
    ends = np.cumsum(length).tolist()
    scan = _DECODER.raw_decode
    out: list[dict[str, Any]] = []
    at = 0
    try:
        for end in ends:
            msg, at = scan(text, at)
            if at != end or type(msg) is not dict:
                raise Layout("not one JSON object a message")
            out.append(msg)
    except (ValueError, RecursionError) as exc:  # json.JSONDecodeError is a ValueError
        raise Layout("a message that is not plain JSON") from exc
    return out


def _stamps(msgs: list[dict[str, Any]]) -> Arr:
    """``timestamp`` objects -> integer nanoseconds (int64, (N,))."""
    try:
        stamps = [m["timestamp"] for m in msgs]
        secs = [s["sec"] for s in stamps]
        nsecs = [s["nsec"] for s in stamps]
    except (KeyError, TypeError) as exc:
        raise Layout("a message without a timestamp object") from exc
    if any(type(s) is not dict for s in stamps):
        raise Layout("a timestamp that is not an object")
    if any(type(v) is not int for v in secs) or any(type(v) is not int for v in nsecs):
        raise Layout("a timestamp that is not integers")
    try:
        return np.array(
            [s * 1_000_000_000 + n for s, n in zip(secs, nsecs, strict=True)], dtype=np.int64
        )
    except OverflowError as exc:
        raise Layout("a timestamp beyond int64 nanoseconds") from exc


def _numbers(msgs: list[dict[str, Any]], key: str) -> Arr:
    """A number field of every message (float64, (N,)); integers read as floats."""
    try:
        values = [m[key] for m in msgs]
    except KeyError as exc:
        raise Layout(f"a message without '{key}'") from exc
    if any(type(v) not in _NUMBER for v in values):
        raise Layout(f"'{key}' that is not a number")
    try:
        return np.array([float(v) for v in values], dtype=np.float64)
    except OverflowError as exc:  # an integer beyond any double
        raise Layout(f"'{key}' beyond a double") from exc


def _names(values: list[Any]) -> tuple[Arr, list[str]]:
    """A string field as indexes into its distinct values (first seen first)."""
    if any(type(v) is not str for v in values):
        raise Layout("a name that is not a string")
    seen: dict[str, int] = {}
    index = np.array([seen.setdefault(v, len(seen)) for v in values], dtype=np.int64)
    return index, list(seen)


def _pose2d(raw: Raw, msgs: list[dict[str, Any]]) -> Columns:
    """gridmap.Pose2D: stamp, child frame (``""`` when missing), x, y, theta."""
    child, child_names = _names([m.get("child_frame_id", "") for m in msgs])
    arrays: dict[str, Arr] = {"log_ns": raw.log_ns, "pos": raw.pos, "stamp_ns": _stamps(msgs)}
    arrays.update({k: _numbers(msgs, k) for k in ("x", "y", "theta")})
    arrays["child"] = child
    return Columns(arrays, {"child": child_names})


def _reading(raw: Raw, msgs: list[dict[str, Any]]) -> Columns:
    """gridmap.RangeReading: stamp, sensor name, range (m; NaN and inf as written)."""
    try:
        sensors = [m["sensor"] for m in msgs]
    except KeyError as exc:
        raise Layout("a message without 'sensor'") from exc
    sensor, names = _names(sensors)
    arrays: dict[str, Arr] = {"log_ns": raw.log_ns, "pos": raw.pos, "stamp_ns": _stamps(msgs)}
    arrays.update({"sensor": sensor, "range": _numbers(msgs, "range")})
    return Columns(arrays, {"sensor": names})


def matches(type_name: str, cols: Columns, pos: int, msg: Any) -> bool:
    """True if the row of the message at ``pos`` holds what ``json.loads`` gave for it, read
    as the message-by-message reader reads it."""
    a = cols.arrays
    row = int(np.flatnonzero(a["pos"] == pos)[0])
    stamp = msg["timestamp"]
    got: list[Any] = [int(a["stamp_ns"][row])]
    want: list[Any] = [int(stamp["sec"]) * 1_000_000_000 + int(stamp["nsec"])]
    if type_name == "gridmap.Pose2D":
        got += [cols.names["child"][int(a["child"][row])]]
        got += [float(a[k][row]) for k in ("x", "y", "theta")]
        want += [str(msg.get("child_frame_id", ""))]
        want += [float(msg[k]) for k in ("x", "y", "theta")]
    else:
        got += [cols.names["sensor"][int(a["sensor"][row])], float(a["range"][row])]
        want += [str(msg["sensor"]), float(msg["range"])]
    return all(
        (g == w) or (isinstance(w, float) and w != w and g != g)
        for g, w in zip(got, want, strict=True)
    )
