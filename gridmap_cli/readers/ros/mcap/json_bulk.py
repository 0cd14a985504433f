"""Bulk decoding of gridmap's own JSON channels (``gridmap.Pose2D``, ``gridmap.RangeReading``).

The MCAP reader hands over the raw bytes of many messages of one channel at once
(:class:`~gridmap_cli.readers.ros.bulk.Raw`). Two ways, the first that applies:

- msgspec decodes each message, from its own bytes, into a typed struct of the fields gridmap
  reads (integer stamps, numbers, names; ``schemas/mcap-log.md``). It takes strict JSON only and
  checks the types as it parses, so it refuses what the next way must look at: NaN and Infinity
  (which Python's ``json`` writes by default), numbers beyond a double, a string or ``true``
  where a number belongs; and a batch with bytes that are not UTF-8 goes the next way too
  (msgspec does not read the fields it skips, ``json`` does). Where it takes a message, its
  values are the ones ``json.loads`` gives, to the bit (tests/readers/test_json_bulk_typed.py
  holds it to that).
- any other batch (the messages of a few chunks): one ``json`` decoder parses each message from
  its own first byte in a tight loop, and a message must end exactly where the next begins.

The values are then turned into columns (:class:`~gridmap_cli.readers.ros.bulk.Columns`) as
:mod:`~gridmap_cli.readers.ros.bulk` gives them for ROS messages. Anything else (text that is
not ASCII in the second way, a string where a number belongs, a malformed message) raises
:class:`~gridmap_cli.readers.ros.bulk.Layout`, and the channel is read message by message,
which accepts what it accepts and names a bad message.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from operator import attrgetter
from typing import Any

import msgspec
import numpy as np

from gridmap_cli.readers.ros.bulk import Arr, Columns, Layout, Raw, _ragged_index

#: gridmap's JSON message types decoded in bulk.
JSON_TYPES = frozenset({"gridmap.Pose2D", "gridmap.RangeReading"})

_DECODER = json.JSONDecoder()
_NUMBER = (float, int)


# ---------------------------------------------------------------------- typed (msgspec)
# gc=False: the structs hold only numbers and strings, never a cycle, and the collector need
# not track hundreds of thousands of them
class _Stamp(msgspec.Struct, gc=False):
    sec: int
    nsec: int


class _Pose2D(msgspec.Struct, gc=False):
    timestamp: _Stamp
    x: float
    y: float
    theta: float
    child_frame_id: str = ""


class _RangeReading(msgspec.Struct, gc=False):
    timestamp: _Stamp
    sensor: str
    range: float


_TYPED: dict[str, Callable[[Any], Any]] = {
    "gridmap.Pose2D": msgspec.json.Decoder(_Pose2D).decode,
    "gridmap.RangeReading": msgspec.json.Decoder(_RangeReading).decode,
}
_SEC, _NSEC = attrgetter("timestamp.sec"), attrgetter("timestamp.nsec")
#: seconds and nanoseconds below these cannot overflow int64 nanoseconds, in any combination
_SEC_SAFE, _NSEC_SAFE = 9_000_000_000, 10**17


def _utf8(text: bytes) -> bool:
    """True if ``json.loads`` can read ``text`` as UTF-8 (it lets encoded surrogates through)."""
    try:
        text.decode("utf-8", "surrogatepass")
    except UnicodeDecodeError:
        return False
    return True


def _typed(type_name: str, raw: Raw) -> Columns | None:
    """The messages as columns, if msgspec takes every one (else None)."""
    data = raw.buf.tobytes()  # bytes slice several times faster than a memoryview of numpy's
    start = raw.offset.tolist()
    end = (raw.offset + raw.length).tolist()
    texts = list(map(data.__getitem__, map(slice, start, end)))
    if not all(map(bytes.isascii, texts)) and not all(map(_utf8, texts)):
        return None  # msgspec does not look at the bytes of the fields it skips; json does
    try:
        msgs = list(map(_TYPED[type_name], texts))
    except (msgspec.DecodeError, ValueError, RecursionError):  # ValidationError included
        return None
    n = len(msgs)
    arrays: dict[str, Arr] = {"log_ns": raw.log_ns, "pos": raw.pos}
    arrays["stamp_ns"] = _stamp_ns(list(map(_SEC, msgs)), list(map(_NSEC, msgs)))
    fields = ("x", "y", "theta") if type_name == "gridmap.Pose2D" else ("range",)
    for key in fields:
        arrays[key] = np.fromiter(map(attrgetter(key), msgs), np.float64, n)
    name = "child" if type_name == "gridmap.Pose2D" else "sensor"
    attr = "child_frame_id" if type_name == "gridmap.Pose2D" else "sensor"
    arrays[name], names = _index(list(map(attrgetter(attr), msgs)))  # str: msgspec checked
    return Columns(arrays, {name: names})


def decode(type_name: str, raw: Raw) -> Columns:
    """Decode raw JSON messages of ``type_name`` (one of :data:`JSON_TYPES`)."""
    cols = _typed(type_name, raw)
    if cols is not None:
        return cols
    msgs = _parse(raw)
    if type_name == "gridmap.Pose2D":
        return _pose2d(raw, msgs)
    return _reading(raw, msgs)


# ---------------------------------------------------------------------- any JSON (json)
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


def _stamp_ns(secs: list[Any], nsecs: list[Any]) -> Arr:
    """Integer seconds and nanoseconds -> integer nanoseconds (int64, (N,)); in numpy where no
    sum can overflow, else exactly in Python."""
    try:
        sec, nsec = np.array(secs, dtype=np.int64), np.array(nsecs, dtype=np.int64)
    except OverflowError:
        pass
    else:
        small = (sec > -_SEC_SAFE) & (sec < _SEC_SAFE) & (nsec > -_NSEC_SAFE) & (nsec < _NSEC_SAFE)
        if np.all(small):
            return sec * 1_000_000_000 + nsec
    try:
        return np.array(
            [s * 1_000_000_000 + n for s, n in zip(secs, nsecs, strict=True)], dtype=np.int64
        )
    except OverflowError as exc:
        raise Layout("a timestamp beyond int64 nanoseconds") from exc


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
    return _stamp_ns(secs, nsecs)


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
    return _index(values)


def _index(values: list[str]) -> tuple[Arr, list[str]]:
    """Strings as indexes into their distinct values (first seen first)."""
    seen = {v: i for i, v in enumerate(dict.fromkeys(values))}
    index = np.fromiter(map(seen.__getitem__, values), np.int64, len(values))
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
