"""Bulk decoding of gridmap's JSON channels (gridmap_cli/readers/ros/mcap/json_bulk.py): the same
canonical log and the same errors as decoding message by message."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import Writer

from gridmap_cli.errors import InputFileError
from gridmap_cli.readers.ros.bulk import Layout, Raw
from gridmap_cli.readers.ros.mcap import bulk as mcap_bulk
from gridmap_cli.readers.ros.mcap import json_bulk
from gridmap_cli.readers.ros.mcap.log import McapSource, read_mcap
from tests.readers.mcap_helpers import S
from tests.readers.test_mcap_bulk import ROOT, assert_same, both

TOPICS = ["/sensors", "/odom", "/ground_truth", "/range"]


def write_log(path: Path, odom: list[bytes], ranges: list[bytes], chunk_size: int = 1024) -> Path:
    """A gridmap JSON log (schemas/mcap-log.md) with the given message texts, stamped 0.1 s
    apart; small chunks, so a channel spans several."""
    with open(path, "wb") as handle:
        w = Writer(handle, chunk_size=chunk_size)
        w.start(profile="", library="gridmap tests")
        ids = {}
        for topic, schema in (("/sensors", "gridmap.RangeSensor"), ("/odom", "gridmap.Pose2D"),
                              ("/ground_truth", "gridmap.Pose2D"),
                              ("/range", "gridmap.RangeReading")):  # fmt: skip
            sid = w.register_schema(schema, "jsonschema", b'{"type": "object"}')
            ids[topic] = w.register_channel(topic, "json", sid)
        for name, y in (("left", 0.1), ("right", -0.1)):
            sensor = {"timestamp": {"sec": 1, "nsec": 0}, "name": name, "kind": "sonar",
                      "x": 0.0, "y": y, "yaw": 0.5, "beam_width": 0.4363323129985824,
                      "min_range": 0.15, "max_range": 4.335}  # fmt: skip
            w.add_message(ids["/sensors"], S, json.dumps(sensor).encode(), S)
        for k in range(max(len(odom), len(ranges))):
            ns = S + k * S // 10
            if k < len(odom):
                w.add_message(ids["/odom"], ns, odom[k], ns)
                truth = odom[k].replace(b'"odom"', b'"world"')
                w.add_message(ids["/ground_truth"], ns, truth, ns)
            if k < len(ranges):
                w.add_message(ids["/range"], ns, ranges[k], ns)
        w.add_metadata("gridmap", {"robot": "p3at"})
        w.finish()
    return path


def pose(k: int, **change: object) -> bytes:
    ns = S + k * S // 10
    msg: dict[str, object] = {"timestamp": {"sec": ns // S, "nsec": ns % S}, "frame_id": "odom",
                              "child_frame_id": "base_link", "x": 0.1 * k, "y": 0.01 * k,
                              "theta": 0.02 * k}  # fmt: skip
    msg.update(change)
    return json.dumps(msg, separators=(",", ":")).encode()


def reading(
    k: int, sensor: str, value: float, zero_stamp: bool = False, compact: bool = False
) -> bytes:
    ns = 0 if zero_stamp else S + k * S // 10
    stamp = {"sec": ns // S, "nsec": ns % S}
    separators = (",", ":") if compact else None  # gridmap's layout, or json.dumps' default
    msg = {"timestamp": stamp, "sensor": sensor, "range": value}
    return json.dumps(msg, separators=separators).encode()


def busy(path: Path, compact: bool = False, **odd: bytes) -> Path:
    """NaN, Infinity, integers, zero stamps, a sensor /sensors does not describe (its first
    reading NaN), a pose without child frame; ``odd`` replaces message k of /odom
    (``odom<k>``) or /range (``range<k>``)."""
    odom = [pose(k) for k in range(60)]
    odom[5] = pose(5, x=1, theta=0)  # integers
    odom[7] = json.dumps(json.loads(pose(7)) | {"child_frame_id": ""}).encode()
    values = [1.0, float("nan"), float("inf"), 2, 4.335, 0.5]
    ranges = []
    for k in range(60):
        sensor = ("left", "right", "extra")[k % 3]
        value = float("nan") if k == 2 else values[k % len(values)]
        ranges.append(reading(k, sensor, value, zero_stamp=k == 4, compact=compact))
    for key, text in odd.items():
        target = odom if key.startswith("odom") else ranges
        target[int(key.removeprefix("odom").removeprefix("range"))] = text
    return write_log(path, odom, ranges)


def test_bundled_json_sample(monkeypatch: pytest.MonkeyPatch) -> None:
    path = ROOT / "samples" / "corridor_loop.mcap"
    batches, left = McapSource(path).bulk(TOPICS)
    assert left == ["/sensors"]
    assert sorted(b.topic for b in batches) == ["/ground_truth", "/odom", "/range"]
    bulk, one_by_one = both(path, monkeypatch)
    assert_same(bulk, one_by_one)
    assert bulk.truth is not None and one_by_one.truth is not None
    assert bulk.truth.x_m.tolist() == one_by_one.truth.x_m.tolist()
    assert len(bulk.readings) > 20_000


@pytest.mark.parametrize("compact", [True, False])
def test_bulk_equals_message_by_message(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, compact: bool
) -> None:
    path = busy(tmp_path / "busy.mcap", compact)
    _, left = McapSource(path).bulk(TOPICS)
    assert left == ["/sensors"]
    bulk, one_by_one = both(path, monkeypatch)
    assert_same(bulk, one_by_one)
    assert bulk.sensor_names == ("left", "right", "extra")
    assert len(bulk.poses) == 60


@pytest.mark.parametrize(
    ("odd", "topic", "bulk"),
    [
        # JSON that msgspec takes: whitespace around, no frames, a name that is not ASCII
        ({"odom30": b' {"timestamp":{"sec":4,"nsec":0},"x":1.0,"y":0.0,"theta":0.0} '}, "/odom",
         True),
        ({"odom30": pose(30, child_frame_id="b\u00e4se")}, "/odom", True),
        # not on /range, whose NaN readings send every chunk to the json way, which takes ASCII
        ({"range40": b'{"timestamp":{"sec":5,"nsec":0},"sensor":"l\xc3\xa9ft","range":1.0}'},
         "/range", False),
        # and what msgspec refuses: a string or true for a number, a float stamp, two objects,
        # bytes that are not UTF-8 in a field it skips (json refuses the message)
        ({"odom30": pose(30, x="3.0")}, "/odom", False),
        ({"odom30": pose(30).replace(b'"odom"', b'"od\x80om"')}, "/odom", False),
        ({"odom30": pose(30, timestamp={"sec": 4.0, "nsec": 0})}, "/odom", False),
        ({"range40": b'{"timestamp":{"sec":5,"nsec":0},"sensor":"left","range":1.0},{}'},
         "/range", False),
        ({"range40": b'{"timestamp":{"sec":5,"nsec":0},"sensor":"left","range":true}'}, "/range",
         False),
    ],
)  # fmt: skip
def test_unusual_messages_same_log_as_message_by_message(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, odd: dict[str, bytes], topic: str, bulk: bool
) -> None:
    path = busy(tmp_path / "odd.mcap", compact=True, **odd)
    _, left = McapSource(path).bulk(TOPICS)
    assert (topic not in left) == bulk, left
    try:
        bulk_log, one_by_one = both(path, monkeypatch)
    except InputFileError as exc:  # not JSON at all: the message-by-message error, both ways
        monkeypatch.setattr(mcap_bulk, "BULK_DECODE", False)
        with pytest.raises(InputFileError) as err:
            read_mcap(path)
        assert str(err.value) == str(exc)
        return
    assert_same(bulk_log, one_by_one)


def test_negative_range_same_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = busy(tmp_path / "bad.mcap", range41=reading(41, "right", -0.5))
    messages = []
    for in_bulk in (True, False):
        monkeypatch.setattr(mcap_bulk, "BULK_DECODE", in_bulk)
        with pytest.raises(InputFileError) as err:
            read_mcap(path)
        messages.append(str(err.value))
    assert messages[0] == messages[1]
    assert "/range at log time 5.100000000 s: negative range -0.5" in messages[0]


def raw_of(texts: list[bytes]) -> Raw:
    """Messages back to back, then one byte of something else."""
    data = b"".join(texts) + b"\x05"
    length = np.array([len(t) for t in texts], dtype=np.int64)
    rows = np.arange(len(texts), dtype=np.int64)
    return Raw(np.frombuffer(data, np.uint8), np.cumsum(length) - length, length, rows, rows)


def compact_reading(sec: str, nsec: str, sensor: str, value: str) -> bytes:
    stamp = f'{{"timestamp":{{"sec":{sec},"nsec":{nsec}}}'
    return f'{stamp},"sensor":"{sensor}","range":{value}}}'.encode()


def test_compact_layout_values() -> None:
    texts = [
        compact_reading("1", "5", "s0", "NaN"),
        compact_reading("-12", "999999999", "a-b", "2"),
        compact_reading("0", "0", "s0", "-1.5e-3"),
        compact_reading("-0", "7", "", "Infinity"),
        compact_reading("3", "0", "sonar_long_name", "0.942"),
    ]
    assert json_bulk._typed("gridmap.RangeReading", raw_of(texts)) is None  # NaN: json's
    for cols in (
        json_bulk.decode("gridmap.RangeReading", raw_of(texts)),
        json_bulk._typed("gridmap.RangeReading", raw_of(texts[1:3] + texts[4:])),
    ):
        assert cols is not None
        if len(cols.arrays["range"]) == 5:
            assert cols.arrays["stamp_ns"].tolist() == [S + 5, -11 * S - 1, 0, 7, 3 * S]
            assert cols.name_column("sensor") == ["s0", "a-b", "s0", "", "sonar_long_name"]
            assert cols.arrays["range"].tolist()[1:] == [2.0, -0.0015, math.inf, 0.942]
            assert math.isnan(cols.arrays["range"][0])
        else:
            assert cols.arrays["stamp_ns"].tolist() == [-11 * S - 1, 0, 3 * S]
            assert cols.name_column("sensor") == ["a-b", "s0", "sonar_long_name"]
            assert cols.arrays["range"].tolist() == [2.0, -0.0015, 0.942]


@pytest.mark.parametrize(
    "odd",
    [
        compact_reading("01", "5", "s0", "1"),  # a leading zero is not JSON
        compact_reading("1", "5", "s0", "1."),
        compact_reading("1", "5", "s0", "+1"),
        compact_reading("1", "5", "s0", "1e"),
        compact_reading("1", "5", "s0", "nan"),
        compact_reading("1", "5", "s0", "1.5\x00"),  # json stops at a NUL
        compact_reading("1", "5", "s0", "1") + b"{}",
        b'{"timestamp":{"sec":1,"nsec":5},"sensor":"s0","range":1',
        b'{"timestamp":{"sec":1,"nsec":5},"sensor":"s0","range":1,"frame_id":"\xc3("}',
    ],
)
def test_what_json_refuses_is_not_decoded(odd: bytes) -> None:
    texts = [compact_reading("1", "5", "s0", "1"), odd]
    assert json_bulk._typed("gridmap.RangeReading", raw_of(texts)) is None
    with pytest.raises(Layout):
        json_bulk.decode("gridmap.RangeReading", raw_of(texts))


@pytest.mark.parametrize(
    "other",
    [
        compact_reading("1", "5", "s\\u0030", "1"),  # an escape
        compact_reading("1", "5", "s,0", "1"),
        compact_reading("1234567890", "5", "s0", "1"),  # 10 digits
        compact_reading("1", "5", "s0", "1") + b" \n",
        b'{"timestamp":{"nsec":5,"sec":1},"range":1,"sensor":"s0","frame_id":"x","more":[{}]}',
        reading(3, "s0", 0.25),  # json.dumps' own separators
    ],
)
def test_other_layouts_of_json_are_decoded_as_json_reads_them(other: bytes) -> None:
    texts = [compact_reading("1", "5", "s0", "1"), other]
    cols = json_bulk._typed("gridmap.RangeReading", raw_of(texts))
    assert cols is not None
    msgs = [json.loads(t) for t in texts]
    assert cols.name_column("sensor") == [m["sensor"] for m in msgs]
    assert cols.arrays["range"].tolist() == [float(m["range"]) for m in msgs]
    stamps = [m["timestamp"]["sec"] * S + m["timestamp"]["nsec"] for m in msgs]
    assert cols.arrays["stamp_ns"].tolist() == stamps


def test_numbers_are_the_floats_json_gives() -> None:
    """Every number as ``json.loads`` reads it, to the bit (the sign of zero included), by
    msgspec or, for a chunk it refuses (1e400), by json."""
    spellings = ["0", "-0", "-0.0", "0.1", "1e5", "1E-300", "4.9e-324", "2.2250738585072011e-308",
                 "1.7976931348623157e308", "0.10000000000000000555", "-12.5e+3",
                 "123456789012345678901234567890", "17976931348623159e292", "9007199254740993",
                 "0.30000000000000004", "1e400", "-1e400"]  # fmt: skip
    want = np.array([float(json.loads(v)) for v in spellings], dtype=np.float64)
    texts = [compact_reading("1", "5", "s0", v) for v in spellings]
    cols = json_bulk.decode("gridmap.RangeReading", raw_of(texts))
    assert cols.arrays["range"].view(np.int64).tolist() == want.view(np.int64).tolist()
    finite = np.isfinite(want)  # json reads the others as infinities: msgspec refuses them
    assert finite.sum() == len(spellings) - 3
    kept = [t for t, f in zip(texts, finite.tolist(), strict=True) if f]
    typed = json_bulk._typed("gridmap.RangeReading", raw_of(kept))
    assert typed is not None
    assert typed.arrays["range"].view(np.int64).tolist() == want[finite].view(np.int64).tolist()


def test_stamps_beyond_int64_nanoseconds_are_not_decoded() -> None:
    fits = compact_reading("9223372036", "854775807", "s0", "1")  # int64's largest
    over = compact_reading("9223372036", "854775808", "s0", "1")
    cols = json_bulk._typed("gridmap.RangeReading", raw_of([fits]))
    assert cols is not None and cols.arrays["stamp_ns"].tolist() == [2**63 - 1]
    for text in (over, compact_reading("1", "18446744073709551616", "s0", "1")):
        with pytest.raises(Layout, match="beyond int64"):
            json_bulk.decode("gridmap.RangeReading", raw_of([fits, text]))
