"""Long MCAP recordings with their range readings left in the file: the held log's readings and
map, bit for bit; recordings the streamed read cannot reproduce cheaply are read held."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap_ros2.writer import Writer as Ros2Writer

from gridmap_cli.mapping import pipeline
from gridmap_cli.readers import read_log
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros.mcap import bulk as mcap_bulk
from gridmap_cli.readers.ros.mcap import stream as mcap_stream
from gridmap_cli.records import RangeReadings
from tests.helpers import built, run
from tests.readers.mcap_helpers import Recording, S, drive, sonar_range, static_tf
from tests.readers.test_csv_stream import joined, same_readings

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
LOG = SAMPLES / "corridor_loop_ros2.mcap"
STREAM = ReadOptions(stream=True)


@pytest.fixture
def streaming(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every MCAP file streams, and build cuts chunks of a few scans."""
    monkeypatch.setattr(mcap_stream, "STREAM_FROM_BYTES", 0)
    monkeypatch.setattr(pipeline, "SYNC_CHUNK_READINGS", 700)


@pytest.mark.usefixtures("streaming")
def test_a_streamed_recording_reads_as_the_held_one() -> None:
    held = read_log(LOG)
    streamed = read_log(LOG, None, STREAM)
    assert held.stream is None and streamed.stream is not None
    assert len(streamed.readings) == 0 and streamed.reading_count == len(held.readings)
    assert streamed.reading_span() == held.reading_span()
    counts = np.bincount(held.readings.sensor, minlength=len(held.sensor_names))
    assert np.array_equal(streamed.stream.counts, counts)
    for _ in range(2):  # read again for each pass
        blocks = list(streamed.stream.readings())
        assert len(blocks) > 1
        assert same_readings(joined(blocks), held.readings)
    chunks = [len(c) for c in streamed.reading_chunks(700)]
    assert chunks == [len(c) for c in held.reading_chunks(700)] and len(chunks) > 10
    for a, b in ((held.poses, streamed.poses), (held.truth, streamed.truth)):
        assert a is not None and b is not None
        assert all(np.array_equal(getattr(a, k), getattr(b, k)) for k in vars(a))
    assert (held.sensor_names, held.sensors) == (streamed.sensor_names, streamed.sensors)


def test_a_small_recording_is_held() -> None:
    assert read_log(LOG, None, STREAM).stream is None  # below STREAM_FROM_BYTES


def test_the_threshold_variable_lowers_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(mcap_stream, "STREAM_FROM_BYTES", 0)
    monkeypatch.setattr(mcap_stream, "SCAN_STREAM_FROM_BYTES", 0)
    assert read_log(LOG, None, STREAM).stream is not None


@pytest.mark.parametrize(
    "flags",
    [
        (),
        ("--sensors", "sonar1*", "--sensors", "!sonar12"),
        ("--mode", "error-aware", "--odometry-coefficient", "range_m_per_m=0.01",
         "--odometry-coefficient", "bearing_rad_per_rad=0.02"),
    ],
    ids=["standard", "sensors", "error-aware"],
)  # fmt: skip
def test_a_recording_above_the_threshold_maps_as_the_held_one_byte_for_byte(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, flags: tuple[str, ...]
) -> None:
    monkeypatch.setattr(pipeline, "SYNC_CHUNK_READINGS", 700)  # many chunks, as a long log has
    held = built(tmp_path, "held", str(LOG), *flags)
    monkeypatch.setattr(mcap_stream, "STREAM_FROM_BYTES", LOG.stat().st_size)
    calls: list[bool] = []
    read_streamed = mcap_stream.read_streamed

    def counted(path: Path, options: ReadOptions):  # type: ignore[no-untyped-def]
        log = read_streamed(path, options)
        calls.append(log is not None and log.stream is not None)
        return log

    monkeypatch.setattr(mcap_stream, "read_streamed", counted)
    assert built(tmp_path, "streamed", str(LOG), *flags) == held
    assert calls == [True]


class SmallChunks(Recording):
    """A ROS 2 recording of a few messages a chunk."""

    def __init__(self, path: Path) -> None:
        self.ros = 2
        self.handle = open(path, "wb")  # noqa: SIM115 - closed by close()
        self.writer = Ros2Writer(self.handle, chunk_size=256)
        self.schemas = {}


def sonar_recording(path: Path, stamps_ns: list[int]) -> Path:
    """ROS 2, small chunks: odometry, a mounted sonar, and one reading each at log times 1 s,
    1.01 s, ... whose header stamps are ``stamps_ns``."""
    with SmallChunks(path) as rec:
        static_tf(rec, rec.transform(0, "base_link", "s0", 0.0, 0.0, 0.0))
        drive(rec)
        for k, stamp in enumerate(stamps_ns):
            log_ns = S + k * S // 100
            rec.write("/sonar", "sensor_msgs/Range", log_ns, sonar_range(rec, stamp, "s0", 1.0))
    return path


@pytest.mark.usefixtures("streaming")
def test_a_recording_in_stamp_order_streams(tmp_path: Path) -> None:
    path = sonar_recording(tmp_path / "ok.mcap", [S + k * S // 100 for k in range(60)])
    held, streamed = read_log(path), read_log(path, None, STREAM)
    assert streamed.stream is not None
    blocks = list(streamed.stream.readings())
    assert len(blocks) > 1 and same_readings(joined(blocks), held.readings)


@pytest.mark.usefixtures("streaming")
def test_header_stamps_out_of_order_across_chunks_read_held(tmp_path: Path) -> None:
    stamps = [S + k * S // 100 for k in range(60)]
    stamps[50] = S  # a late message stamped at the start: its chunk comes after earlier ones
    path = sonar_recording(tmp_path / "late.mcap", stamps)
    held, streamed = read_log(path), read_log(path, None, STREAM)
    assert streamed.stream is None
    assert same_readings(streamed.readings, held.readings)
    assert isinstance(held.readings, RangeReadings) and held.readings.stamp_ns[1] == S


@pytest.mark.usefixtures("streaming")
def test_several_range_topics_read_held(tmp_path: Path) -> None:
    path = tmp_path / "two.mcap"
    with Recording(path) as rec:
        static_tf(rec, rec.transform(0, "base_link", "s0", 0.0, 0.0, 0.0),
                  rec.transform(0, "base_link", "s1", 0.0, 0.0, 1.0))  # fmt: skip
        drive(rec)
        rec.write("/sonar0", "sensor_msgs/Range", S, sonar_range(rec, S, "s0", 1.0))
        rec.write("/sonar1", "sensor_msgs/Range", S, sonar_range(rec, S, "s1", 1.0))
    assert read_log(path, None, STREAM).stream is None


@pytest.mark.usefixtures("streaming")
def test_message_by_message_decoding_reads_held(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(mcap_bulk, "BULK_DECODE", False)
    assert read_log(LOG, None, STREAM).stream is None


SCAN = ReadOptions(range_topics=("/scan",))
SCAN_STREAM = ReadOptions(range_topics=("/scan",), stream=True)


@pytest.fixture(scope="module")
def laser_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated p3at-lms200 run as ROS 2 MCAP: odometry, sonars and a 181-beam LaserScan."""
    out = tmp_path_factory.mktemp("laser") / "laser.mcap"
    world, route = SAMPLES / "worlds" / "office.yaml", SAMPLES / "paths" / "office.yaml"
    code, _, stderr = run("simulate", str(world), str(route), "--robot", "p3at-lms200",
                          "--encoding", "ros2", "--duration", "60",
                          "-o", str(out), "-q")  # fmt: skip
    assert code == 0, stderr
    return out


@pytest.mark.usefixtures("streaming")
def test_a_streamed_laser_recording_reads_as_the_held_one(laser_log: Path) -> None:
    held = read_log(laser_log, None, SCAN)
    streamed = read_log(laser_log, None, SCAN_STREAM)
    assert held.stream is None and streamed.stream is not None
    assert len(held.sensor_names) == 181 and held.readings.range_m.max() == 8.0  # no echo kept
    assert streamed.reading_count == len(held.readings)
    assert streamed.reading_span() == held.reading_span()
    counts = np.bincount(held.readings.sensor, minlength=len(held.sensor_names))
    assert np.array_equal(streamed.stream.counts, counts)
    blocks = list(streamed.stream.readings())
    assert len(blocks) > 1 and same_readings(joined(blocks), held.readings)
    assert (held.sensor_names, held.sensors) == (streamed.sensor_names, streamed.sensors)


def test_a_laser_recording_above_the_threshold_maps_as_the_held_one_byte_for_byte(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, laser_log: Path
) -> None:
    monkeypatch.setattr(pipeline, "SYNC_CHUNK_READINGS", 5000)
    flags = (str(laser_log), "--range-topic", "/scan")
    held = built(tmp_path, "held", *flags)
    monkeypatch.setattr(mcap_stream, "STREAM_FROM_BYTES", 0)
    monkeypatch.setattr(mcap_stream, "SCAN_STREAM_FROM_BYTES", 0)
    calls: list[bool] = []
    read_streamed = mcap_stream.read_streamed

    def counted(path: Path, options: ReadOptions):  # type: ignore[no-untyped-def]
        log = read_streamed(path, options)
        calls.append(log is not None and log.stream is not None)
        return log

    monkeypatch.setattr(mcap_stream, "read_streamed", counted)
    assert built(tmp_path, "streamed", *flags) == held
    assert calls == [True]


def scan(rec: Recording, ns: int, ranges: list[float], frame: str = "laser",
         angle_min: float = -0.5, range_max: float = 4.0) -> dict[str, Any]:  # fmt: skip
    """A 0.5 rad a beam sensor_msgs/LaserScan message as nested dicts."""
    return {"header": rec.header(ns, frame), "angle_min": angle_min,
            "angle_max": angle_min + 1.0,
            "angle_increment": 0.5, "range_min": 0.1, "range_max": range_max,
            "ranges": ranges}  # fmt: skip


def laser_recording(path: Path, changes: dict[int, dict[str, Any]] | None = None) -> Path:
    """ROS 2, small chunks: odometry, mounted lasers and 40 three-beam scans at log times 1 s,
    1.01 s, ..., two a stamp, with NaN, -inf, +inf and ranges at or past a ``range_max`` that
    changes from scan to scan; ``changes`` (scan number -> keyword arguments of :func:`scan`)
    alter some."""
    values = [[1.0, math.nan, 2.5], [math.inf, -math.inf, 3.0], [4.0, 5.0, 0.5]]
    with SmallChunks(path) as rec:
        static_tf(rec, rec.transform(0, "base_link", "laser", 0.1, 0.0, 0.0),
                  rec.transform(0, "base_link", "laser2", 0.0, 0.0, 1.0))  # fmt: skip
        drive(rec)
        for k in range(40):
            stamp = S + (k // 2) * S // 50
            kwargs: dict[str, Any] = {"range_max": 3.0 + (k % 3)}
            kwargs.update((changes or {}).get(k, {}))
            message = scan(rec, stamp, values[k % 3], **kwargs)
            rec.write("/scan", "sensor_msgs/LaserScan", S + k * S // 100, message)
    return path


@pytest.mark.usefixtures("streaming")
def test_scans_stream_with_their_no_echo_and_dropped_beams_as_held(tmp_path: Path) -> None:
    path = laser_recording(tmp_path / "scans.mcap")
    held, streamed = read_log(path), read_log(path, None, STREAM)
    assert streamed.stream is not None
    blocks = list(streamed.stream.readings())
    assert len(blocks) > 1 and same_readings(joined(blocks), held.readings)
    assert held.sensor_names == ("laser_0", "laser_1", "laser_2")
    assert 3.0 in held.readings.range_m.tolist()  # no echo: the first scan's range_max


@pytest.mark.usefixtures("streaming")
def test_a_scan_changing_its_beams_reads_held(tmp_path: Path) -> None:
    path = laser_recording(tmp_path / "changed.mcap", {30: {"angle_min": -0.75}})
    held, streamed = read_log(path), read_log(path, None, STREAM)
    assert streamed.stream is None and len(held.sensor_names) == 6  # three new directions
    assert same_readings(streamed.readings, held.readings)


@pytest.mark.usefixtures("streaming")
def test_several_laser_frames_read_held(tmp_path: Path) -> None:
    path = laser_recording(tmp_path / "two.mcap", {k: {"frame": "laser2"} for k in range(20, 40)})
    held, streamed = read_log(path), read_log(path, None, STREAM)
    assert streamed.stream is None and len(held.sensor_names) == 6
    assert same_readings(streamed.readings, held.readings)


def test_laser_recordings_stream_from_a_smaller_size(
    monkeypatch: pytest.MonkeyPatch, laser_log: Path
) -> None:
    # a laser's beams are about 5 bytes of MCAP each against 40 held: scans stream from
    # SCAN_STREAM_FROM_BYTES, range readings only from STREAM_FROM_BYTES
    size = max(laser_log.stat().st_size, LOG.stat().st_size)
    monkeypatch.setattr(mcap_stream, "SCAN_STREAM_FROM_BYTES", 0)
    monkeypatch.setattr(mcap_stream, "STREAM_FROM_BYTES", size + 1)
    assert read_log(laser_log, None, SCAN_STREAM).stream is not None
    assert read_log(LOG, None, STREAM).stream is None  # sonar ranges only: held
    monkeypatch.setattr(mcap_stream, "SCAN_STREAM_FROM_BYTES", size + 1)
    assert read_log(laser_log, None, SCAN_STREAM).stream is None
