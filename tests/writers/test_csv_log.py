"""The CSV log writer: what it writes reads back bit for bit; what it cannot write, it refuses."""

from __future__ import annotations

import dataclasses
import io
import math
from decimal import Decimal
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gridmap_cli.errors import GridmapError
from gridmap_cli.readers.text.csv_log import read_csv_log, seconds_to_ns
from gridmap_cli.records import PoseTrack, RangeLog, RangeReadings
from gridmap_cli.writers import csv_log as csv_log_writer
from gridmap_cli.writers.csv_log import ns_to_seconds_text, save_csv_log, write_csv_log


def track(stamps: list[int], x: list[float], y: list[float], th: list[float]) -> PoseTrack:
    return PoseTrack(
        stamp_ns=np.asarray(stamps, dtype=np.int64),
        x_m=np.asarray(x, dtype=np.float64),
        y_m=np.asarray(y, dtype=np.float64),
        theta_rad=np.asarray(th, dtype=np.float64),
    )


def readings(rows: list[tuple[int, int, float]]) -> RangeReadings:
    """Readings from (stamp_ns, sensor index, range_m) rows, given in stamp-then-sensor order."""
    return RangeReadings(
        stamp_ns=np.asarray([r[0] for r in rows], dtype=np.int64),
        sensor=np.asarray([r[1] for r in rows], dtype=np.int32),
        range_m=np.asarray([r[2] for r in rows], dtype=np.float64),
    )


# Epoch stamps with nanoseconds (a float of seconds cannot hold them), and pose values that a
# fixed number of decimals would spoil: thirds, a subnormal, huge and tiny magnitudes, -0.0.
STAMPS = [1_700_000_000_000_000_001, 1_700_000_000_100_000_000, 1_700_000_000_123_456_789]
ODOM = track(
    STAMPS,
    [0.0, 1 / 3, -2.5e-300],
    [-0.0, 5e-324, 1e300],
    [math.pi, -math.pi / 3, 0.1 + 0.2],
)
TRUTH = track(STAMPS, [10.0, 10.1, 2 / 7], [-3.0, -3.000000000000001, 7e-17], [0.5, -1.25, 3.0])


def sample_log(truth: PoseTrack | None = TRUTH) -> RangeLog:
    return RangeLog(
        source="memory",
        poses=ODOM,
        # sonar1 silent on the first row and sonar0 on the second; inf is a "no echo" reading
        readings=readings(
            [
                (STAMPS[0], 0, 1.5),
                (STAMPS[0], 2, 4.335),
                (STAMPS[1], 1, 0.1 + 0.7),
                (STAMPS[1], 2, math.inf),
                (STAMPS[2], 0, 2 / 3),
                (STAMPS[2], 1, 1e-3),
                (STAMPS[2], 2, 3.999999999999999),
            ]
        ),
        sensor_names=("sonar0", "sonar1", "sonar2"),
        truth=truth,
        metadata={"gridmap-csv": "1", "robot": "p3at", "note": "written by a test"},
    )


def bits(a: npt.NDArray[np.float64]) -> list[int]:
    """The IEEE bit patterns of a float array: equal only if every value is bit-identical."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64).tolist()


def assert_same_track(got: PoseTrack, want: PoseTrack) -> None:
    assert got.stamp_ns.tolist() == want.stamp_ns.tolist()
    for name in ("x_m", "y_m", "theta_rad"):
        assert bits(getattr(got, name)) == bits(getattr(want, name)), name


def round_trip(log: RangeLog) -> tuple[str, RangeLog]:
    handle = io.StringIO(newline="")
    write_csv_log(log, handle)
    text = handle.getvalue()
    return text, read_csv_log(io.StringIO(text, newline=""), "round-trip.csv")


# --- round trips ---------------------------------------------------------------------------------


def test_written_log_reads_back_identical() -> None:
    log = sample_log()
    text, back = round_trip(log)
    assert back.metadata == log.metadata
    assert back.sensor_names == log.sensor_names
    assert_same_track(back.poses, log.poses)
    assert back.truth is not None
    assert_same_track(back.truth, TRUTH)
    assert back.readings.stamp_ns.tolist() == log.readings.stamp_ns.tolist()
    assert back.readings.sensor.tolist() == log.readings.sensor.tolist()
    assert bits(back.readings.range_m) == bits(log.readings.range_m)
    # the layout itself: comment block, then the header with truth last
    lines = text.splitlines()
    assert lines[:4] == [
        "# gridmap-csv: 1",
        "# robot: p3at",
        "# note: written by a test",
        "time,x,y,theta,sonar0,sonar1,sonar2,true_x,true_y,true_theta",
    ]
    assert len(lines) == 4 + len(STAMPS)
    # a silent sensor is an empty field, and the time is exact decimal seconds
    first = ["1700000000.000000001", "0.0", "-0.0", repr(math.pi), "1.5", ""]
    assert lines[4].split(",")[:6] == first


def test_log_without_truth_has_no_truth_columns() -> None:
    text, back = round_trip(sample_log(truth=None))
    assert text.splitlines()[3] == "time,x,y,theta,sonar0,sonar1,sonar2"
    assert back.truth is None
    assert_same_track(back.poses, ODOM)


finite = st.floats(allow_nan=False, allow_infinity=False)


@given(
    start=st.integers(-(10**18), 10**18),
    steps=st.lists(st.integers(1, 10**12), min_size=0, max_size=8),
    data=st.data(),
)
def test_any_finite_poses_and_ranges_round_trip_bit_exact(
    start: int, steps: list[int], data: st.DataObject
) -> None:
    stamps = [start + sum(steps[:i]) for i in range(len(steps) + 1)]
    n = len(stamps)
    poses = [data.draw(st.lists(finite, min_size=n, max_size=n)) for _ in range(6)]
    ranges = data.draw(
        st.lists(
            st.one_of(st.none(), st.floats(min_value=0.0, allow_nan=False)),
            min_size=2 * n,
            max_size=2 * n,
        )
    )
    rows = [(stamps[i // 2], i % 2, r) for i, r in enumerate(ranges) if r is not None]
    log = RangeLog(
        source="memory",
        poses=track(stamps, *poses[:3]),
        readings=readings(rows),
        sensor_names=("a", "b"),
        truth=track(stamps, *poses[3:]),
        metadata={"seed": str(start)},
    )
    _, back = round_trip(log)
    assert_same_track(back.poses, log.poses)
    assert back.truth is not None and log.truth is not None
    assert_same_track(back.truth, log.truth)
    assert back.readings.stamp_ns.tolist() == log.readings.stamp_ns.tolist()
    assert back.readings.sensor.tolist() == log.readings.sensor.tolist()
    assert bits(back.readings.range_m) == bits(log.readings.range_m)
    assert back.metadata == {"gridmap-csv": "1", "seed": str(start)}  # the writer adds the version


# --- times as text -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("stamp_ns", "text"),
    [
        (0, "0.0"),
        (1, "0.000000001"),
        (100_000_000, "0.1"),
        (1_000_000_000, "1.0"),
        (1_500_000_000, "1.5"),
        (12_345_678_900, "12.3456789"),
        (1_700_000_000_123_456_789, "1700000000.123456789"),
        (-1, "-0.000000001"),
        (-500_000_000, "-0.5"),
        (-1_500_000_000, "-1.5"),
        (-2_000_000_000, "-2.0"),
        (-1_700_000_000_000_000_010, "-1700000000.00000001"),
    ],
)
def test_ns_to_seconds_text(stamp_ns: int, text: str) -> None:
    assert ns_to_seconds_text(stamp_ns) == text


@given(st.integers(-(2**63 - 1), 2**63 - 1))  # every int64 stamp; beyond, the parser refuses
def test_seconds_text_is_exact_and_reads_back(stamp_ns: int) -> None:
    text = ns_to_seconds_text(stamp_ns)
    # exact decimal value, independently of gridmap's parser
    assert Decimal(text) * 1_000_000_000 == stamp_ns
    # one dot, no exponent, no trailing zeros beyond the one after the dot
    whole, dot, frac = text.lstrip("-").partition(".")
    assert dot and whole.isdigit() and frac.isdigit()
    assert frac == "0" or not frac.endswith("0")
    assert seconds_to_ns(text) == stamp_ns


# --- refusals ------------------------------------------------------------------------------------


def odometry_at(*stamps: int) -> PoseTrack:
    n = len(stamps)
    return track(list(stamps), [0.0] * n, [0.0] * n, [0.0] * n)


@pytest.mark.parametrize(
    ("reading_ns", "shown"),
    [
        (150_000_000, "0.15"),  # between two odometry rows
        (300_000_000, "0.3"),  # after the last
        (-100_000_000, "-0.1"),  # before the first
    ],
)
def test_reading_without_an_odometry_row_is_refused(reading_ns: int, shown: str) -> None:
    log = RangeLog(
        source="memory",
        poses=odometry_at(0, 100_000_000, 200_000_000),
        readings=readings([(0, 0, 1.0), (reading_ns, 0, 2.0)]),
        sensor_names=("sonar0",),
    )
    handle = io.StringIO()
    with pytest.raises(GridmapError) as info:
        write_csv_log(log, handle)
    assert str(info.value) == (
        f"a reading at {shown} s has no odometry row with the same stamp; "
        "the CSV layout keeps readings on odometry rows"
    )
    assert handle.getvalue() == "", "the check must come before the first byte"


@pytest.mark.parametrize("name", ["time", "theta", "true_x", "true_theta", "left,front"])
def test_sensor_names_that_cannot_be_columns_are_refused(name: str) -> None:
    log = RangeLog(
        source="memory",
        poses=odometry_at(0),
        readings=readings([(0, 0, 1.0)]),
        sensor_names=(name,),
    )
    with pytest.raises(GridmapError) as info:
        write_csv_log(log, io.StringIO())
    assert str(info.value) == f"sensor name {name!r} cannot be a CSV column"


# --- saving to a file ----------------------------------------------------------------------------


def test_save_writes_exactly_what_write_produces(tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    save_csv_log(sample_log(), out)
    text, _ = round_trip(sample_log())
    assert out.read_bytes() == text.encode("utf-8")
    assert b"\r" not in out.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv"]


def test_save_of_a_refused_log_leaves_no_file(tmp_path: Path) -> None:
    log = RangeLog(
        source="memory",
        poses=odometry_at(0, 100_000_000),
        readings=readings([(50_000_000, 0, 1.0)]),
        sensor_names=("sonar0",),
    )
    with pytest.raises(GridmapError, match=r"^a reading at 0\.05 s has no odometry row"):
        save_csv_log(log, tmp_path / "run.csv")
    assert list(tmp_path.iterdir()) == [], "neither the target nor a temporary file may remain"


class _DiskFull(Exception):
    pass


def test_failure_halfway_leaves_no_file_and_keeps_an_old_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    real_write = csv_log_writer.write_csv_log

    def write_then_fail(log: RangeLog, handle: io.TextIOBase) -> None:
        real_write(log, handle)  # type: ignore[arg-type]
        handle.flush()
        raise _DiskFull("no space left on device")

    monkeypatch.setattr(csv_log_writer, "write_csv_log", write_then_fail)
    fresh = tmp_path / "fresh.csv"
    with pytest.raises(_DiskFull):
        save_csv_log(sample_log(), fresh)
    assert list(tmp_path.iterdir()) == []

    old = tmp_path / "old.csv"
    old.write_bytes(b"previous log\n")
    with pytest.raises(_DiskFull):
        save_csv_log(sample_log(), old)
    assert old.read_bytes() == b"previous log\n"
    assert [p.name for p in tmp_path.iterdir()] == ["old.csv"]


@pytest.mark.parametrize(
    ("metadata", "message"),
    [
        ({"note": "two\nlines"}, "metadata 'note': 'two\\nlines' cannot be a '# key: value' line"),
        ({"a:b": "x"}, "metadata 'a:b'"),
        ({"": "x"}, "metadata ''"),
    ],
)
def test_metadata_that_would_corrupt_the_header_is_refused(
    metadata: dict[str, str], message: str
) -> None:
    log = dataclasses.replace(sample_log(), metadata=metadata)
    with pytest.raises(GridmapError) as info:
        write_csv_log(log, io.StringIO())
    assert message in str(info.value)


def test_two_readings_for_one_csv_cell_are_refused() -> None:
    log = dataclasses.replace(
        sample_log(), readings=readings([(STAMPS[0], 0, 1.5), (STAMPS[0], 0, 1.6)])
    )
    with pytest.raises(GridmapError, match="two readings of one sensor at one stamp"):
        write_csv_log(log, io.StringIO())


def test_truth_at_other_stamps_is_refused() -> None:
    shifted = track([s + 1 for s in STAMPS], [0, 0, 0], [0, 0, 0], [0, 0, 0])
    with pytest.raises(GridmapError, match="ground truth at the odometry stamps"):
        write_csv_log(sample_log(truth=shifted), io.StringIO())


def test_os_errors_while_writing_are_reported_with_the_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def disk_full(log: RangeLog, handle: io.TextIOBase) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(csv_log_writer, "write_csv_log", disk_full)
    target = tmp_path / "log.csv"
    with pytest.raises(GridmapError) as info:
        save_csv_log(sample_log(), target)
    assert str(info.value) == f"{target}: cannot write the log: No space left on device"
    assert list(tmp_path.iterdir()) == []
