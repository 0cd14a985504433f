"""Bulk decoding of MCAP channels (gridmap_cli/readers/ros/mcap/bulk.py, ros_bulk.py): the same
canonical log and the same errors as decoding message by message."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.errors import InputFileError
from gridmap_cli.readers.ros.mcap import bulk as mcap_bulk
from gridmap_cli.readers.ros.mcap.log import McapSource, read_mcap
from gridmap_cli.records import RangeLog
from tests.readers.mcap_helpers import Recording, S, drive, odometry, sonar_range, static_tf

ROOT = Path(__file__).resolve().parents[2]


def assert_same(a: RangeLog, b: RangeLog) -> None:
    for name in ("poses", "readings"):
        x, y = getattr(a, name), getattr(b, name)
        for f in x.__dataclass_fields__:
            assert np.array_equal(getattr(x, f), getattr(y, f)), (name, f)
    assert (a.truth is None) == (b.truth is None)
    assert a.sensors == b.sensors
    assert a.sensor_names == b.sensor_names


def both(path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[RangeLog, RangeLog]:
    bulk = read_mcap(path).log
    monkeypatch.setattr(mcap_bulk, "BULK_DECODE", False)
    one_by_one = read_mcap(path).log
    monkeypatch.setattr(mcap_bulk, "BULK_DECODE", True)
    return bulk, one_by_one


def busy_log(path: Path, ros: int) -> Path:
    """Two sonars (one with a leading '/'), TF with two transforms a message, odometry and
    ground truth, zero stamps, NaN / inf / negative / beyond-max ranges."""
    tf_type = "tf2_msgs/TFMessage" if ros == 2 else "tf/tfMessage"
    with Recording(path, ros=ros) as rec:
        static_tf(
            rec,
            rec.transform(0, "base_link", "s0", 0.1, 0.0, 0.0),
            rec.transform(0, "base_link", "s1", -0.1, 0.0, math.pi),
        )
        drive(rec, steps=21)
        values = [1.0, math.nan, math.inf, -1.0, 5.0, 0.05, 2.5]
        for k in range(20):
            ns = S + k * S // 10 + 1
            for i, frame in enumerate(("s0", "/s1")):
                msg = sonar_range(rec, 0 if k == 3 else ns, frame, values[(k + i) % len(values)])
                rec.write("/sonar", "sensor_msgs/Range", ns, msg)
            pair = [
                rec.transform(ns, "map", "odom", 0.0, 0.0, 0.0),
                rec.transform(ns, "odom", "base_link", 0.1 * k, 0.0, 0.01 * k),
            ]
            rec.write("/tf", tf_type, ns, {"transforms": pair})
            truth = odometry(rec, ns, 0.1 * k, 0.01, 0.02 * k, frame="map")
            rec.write("/ground_truth", "nav_msgs/Odometry", ns, truth)
    return path


@pytest.mark.parametrize("ros", [1, 2])
def test_bulk_equals_message_by_message(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, ros: int
) -> None:
    path = busy_log(tmp_path / "busy.mcap", ros)
    topics = ["/odom", "/ground_truth", "/sonar", "/tf_static", "/tf"]
    batches, left = McapSource(path).bulk(topics)
    assert left == []  # every channel in bulk
    assert {b.topic for b in batches} == set(topics)
    bulk, one_by_one = both(path, monkeypatch)
    assert_same(bulk, one_by_one)
    assert len(bulk.readings) > 20


def test_bundled_ros2_sample(monkeypatch: pytest.MonkeyPatch) -> None:
    bulk, one_by_one = both(ROOT / "samples" / "corridor_loop_ros2.mcap", monkeypatch)
    assert_same(bulk, one_by_one)


@pytest.mark.parametrize("ros", [1, 2])
def test_bad_limits_same_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, ros: int) -> None:
    path = tmp_path / "bad.mcap"
    with Recording(path, ros=ros) as rec:
        static_tf(rec, rec.transform(0, "base_link", "s0", 0.0, 0.0, 0.0))
        drive(rec)
        for k, rmin in enumerate((0.1, 0.1, 4.0, 0.1)):
            ns = S + k * 1000
            rec.write("/sonar", "sensor_msgs/Range", ns, sonar_range(rec, ns, "s0", 1.0, rmin=rmin))
    messages = []
    for in_bulk in (True, False):
        monkeypatch.setattr(mcap_bulk, "BULK_DECODE", in_bulk)
        with pytest.raises(InputFileError) as err:
            read_mcap(path)
        messages.append(str(err.value))
    assert messages[0] == messages[1]
    assert "need 0 <= min_range < max_range, got 4.0 and 3.0" in messages[0]


@pytest.mark.parametrize("ros", [1, 2])
def test_indexed_messages_as_the_library_yields_them(tmp_path: Path, ros: int) -> None:
    """The messages found through the indexes: those the library's reader yields, in its
    order, for any choice of topics (ties in log time included)."""
    from mcap.reader import make_reader

    from gridmap_cli.readers.ros.mcap.bulk import indexed_messages

    path = busy_log(tmp_path / "busy.mcap", ros)
    with open(path, "rb") as handle:
        reader = make_reader(handle)
        summary = reader.get_summary()
        assert summary is not None
        all_topics = sorted({ch.topic for ch in summary.channels.values()})
        for topics in [all_topics, all_topics[:1], all_topics[1:]]:
            found = indexed_messages(path, handle, summary, topics)
            assert found is not None
            want = list(reader.iter_messages(topics=topics, log_time_order=True))
            got = [(c.id, m.log_time, m.data) for _, c, m in found]
            assert got == [(c.id, m.log_time, bytes(m.data)) for _, c, m in want]
            assert len(got) > 0


@pytest.mark.parametrize("ros", [1, 2])
def test_chunks_decoded_in_groups_as_one_by_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, ros: int
) -> None:
    """Many small chunks, decoded a few at a time (each group's first message checked by the
    library): the log read message by message."""
    from mcap.writer import CompressionType

    from tests.corpus.mcap_edit import edit_mcap

    path = edit_mcap(
        busy_log(tmp_path / "busy.mcap", ros), tmp_path / "small.mcap",
        compression=CompressionType.LZ4, chunk_size=400,
    )  # fmt: skip
    with open(path, "rb") as handle:
        from mcap.reader import make_reader

        summary = make_reader(handle).get_summary()
    assert summary is not None and len(summary.chunk_indexes) > 10
    monkeypatch.setattr(mcap_bulk, "GROUP_BYTES", 3000)
    topics = ["/odom", "/ground_truth", "/sonar", "/tf_static", "/tf"]
    batches, left = McapSource(path).bulk(topics)
    assert {b.topic for b in batches} == set(topics)
    assert left == []
    bulk, one_by_one = both(path, monkeypatch)
    assert_same(bulk, one_by_one)
    assert_same(bulk, read_mcap(tmp_path / "busy.mcap").log)


def test_each_chunk_is_decompressed_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The integrity check hands the bulk read each chunk it decompressed and checked."""
    from gridmap_cli.readers.ros.mcap import integrity

    path = busy_log(tmp_path / "busy.mcap", 2)
    calls: list[str] = []
    decompress = integrity._Walker._decompress

    def counted(self: object, *args: object) -> bytes:
        calls.append("walk")
        return decompress(self, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(integrity._Walker, "_decompress", counted)
    monkeypatch.setattr(mcap_bulk, "_chunk_data", lambda *a: calls.append("again"))
    read = read_mcap(path)
    with open(path, "rb") as handle:
        from mcap.reader import make_reader

        summary = make_reader(handle).get_summary()
    assert summary is not None
    assert calls == ["walk"] * len(summary.chunk_indexes)
    assert len(read.log.readings) > 20


def test_strings_as_the_bytes_say() -> None:
    """Strings of every length, anywhere in the buffer (up to its last byte), found as their
    distinct values in order of first appearance; a NUL inside or bytes that are not UTF-8 are
    not taken."""
    from gridmap_cli.readers.ros.bulk import Layout, _unique_strings

    rng = np.random.default_rng(7)
    words = [b"", b"a", b"base_link", b"sonar_12", b"sonar_1", b"x" * 17, "r\u00e9f".encode()]
    buf = bytearray(rng.integers(1, 256, 300, dtype=np.uint8).tobytes())
    places: list[tuple[int, int]] = []
    for k in range(40):
        text = words[int(rng.integers(len(words)))]
        at = len(buf) - len(text) if k == 39 else int(rng.integers(0, len(buf) - 20))
        buf[at : at + len(text)] = text
        places.append((at, len(text)))
    # later strings may overwrite earlier ones: the expected values are read back from buf
    strings = [bytes(buf[a : a + n]) for a, n in places]
    keep = [i for i, t in enumerate(strings) if b"\0" not in t and _utf8(t)]
    arr = np.frombuffer(bytes(buf), np.uint8)
    start = np.array([places[i][0] for i in keep], np.int64)
    length = np.array([places[i][1] for i in keep], np.int64)
    index, names = _unique_strings(arr, start, length)
    expected = list(dict.fromkeys(strings[i].decode() for i in keep))
    assert names == expected
    assert [names[i] for i in index.tolist()] == [strings[i].decode() for i in keep]
    assert places[-1][0] + places[-1][1] == len(buf)  # the last string ends the buffer
    for bad in (b"ab\0cd", b"\xff\xfe"):
        arr = np.frombuffer(b"zz" + bad + b"zz", np.uint8)
        with pytest.raises(Layout):
            _unique_strings(arr, np.array([0, 2]), np.array([2, len(bad)]))


def _utf8(text: bytes) -> bool:
    try:
        text.decode()
    except UnicodeDecodeError:
        return False
    return True


def test_lexsort_order_is_lexsort() -> None:
    """None for rows already in order, else np.lexsort's order, ties on every key included."""
    from gridmap_cli.readers.ros.bulk import lexsort_order

    rng = np.random.default_rng(3)
    for trial in range(200):
        n = int(rng.integers(0, 30))
        keys = [rng.integers(0, 3, n) for _ in range(int(rng.integers(1, 4)))]
        if trial % 2:  # half of them in order already
            order = np.lexsort(keys)
            keys = [k[order] for k in keys]
        got = lexsort_order(keys)
        want = np.lexsort(keys) if n else np.zeros(0, np.intp)
        if got is None:
            assert np.array_equal(want, np.arange(n))
        else:
            assert np.array_equal(got, want)
            assert not np.array_equal(want, np.arange(n))
