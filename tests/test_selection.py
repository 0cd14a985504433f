"""Choosing sensors and a time window on the canonical log, and leaving out non-sensor columns."""

from __future__ import annotations

import dataclasses
import io
import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gridmap_cli.errors import UsageError
from gridmap_cli.mapping.selection import (
    Selection,
    apply_selection,
    ignore_other_columns,
    keep_sensors,
    names_text,
    parse_time,
    select_sensors,
    select_window,
)
from gridmap_cli.readers.text.csv_log import read_csv_log
from gridmap_cli.records import PoseTrack, RangeLog, RangeReadings
from gridmap_cli.robot import RangeSensor, load_robot

S = 1_000_000_000
APRIL_8 = 1_744_122_870 * S  # 2025-04-08T14:34:30Z


def make_log(
    names: tuple[str, ...] = ("sonar0", "sonar1", "laser_0", "laser_1", "laser_2"),
    t0_ns: int = 0,
    poses: int = 11,
) -> RangeLog:
    """Poses every second from ``t0_ns``; every sensor reads once half a second after each pose
    but the last, its range 1 + its index (so a reading's sensor shows in its range)."""
    stamps = t0_ns + np.arange(poses, dtype=np.int64) * S
    rows = [(float(k), 0.0, 0.0) for k in range(poses)]
    r_stamps = np.repeat(stamps[:-1] + S // 2, len(names))
    sensor = np.tile(np.arange(len(names), dtype=np.int32), poses - 1)
    return RangeLog(
        source="run.log",
        poses=PoseTrack.from_rows(stamps, rows),
        readings=RangeReadings(r_stamps, sensor, 1.0 + sensor.astype(np.float64)),
        sensor_names=names,
        sensors=(RangeSensor("laser_1", 0.1, 0.0, 0.0, 0.0, 0.0, 10.0, kind="laser"),),
        truth=PoseTrack.from_rows(stamps.copy(), rows),
    )


def named(log: RangeLog) -> list[tuple[str, float]]:
    """Each reading as (sensor name, range): what survives re-indexing must match up."""
    return [
        (log.sensor_names[i], float(r))
        for i, r in zip(log.readings.sensor, log.readings.range_m, strict=True)
    ]


# ------------------------------------------------------------------------------------ times


@pytest.mark.parametrize(
    ("text", "offset_ns"),
    [("0", 0), ("12.5", 12_500_000_000), ("1.000000001", 1_000_000_001), ("1e1", 10 * S)],
)
def test_seconds_from_the_start(text: str, offset_ns: int) -> None:
    bound = parse_time(text, "--start")
    assert bound.offset_ns == offset_ns and bound.epoch_ns is None


@pytest.mark.parametrize(
    ("text", "epoch_ns"),
    [
        ("2025-04-08T14:34:30Z", APRIL_8),
        ("2025-04-08T14:34:30", APRIL_8),  # naive: UTC
        ("2025-04-08 14:34:30+00:00", APRIL_8),
        ("2025-04-08T16:34:30+02:00", APRIL_8),
        ("2025-04-08T14:34:30.123456789Z", APRIL_8 + 123_456_789),
        ("2025-04-08T14:34:30,5", APRIL_8 + S // 2),
        ("2025-04-08", APRIL_8 - (14 * 3600 + 34 * 60 + 30) * S),
    ],
)
def test_iso_times(text: str, epoch_ns: int) -> None:
    bound = parse_time(text, "--end")
    assert bound.epoch_ns == epoch_ns and bound.offset_ns is None


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("-1", "--start -1: seconds from the log's start cannot be negative"),
        ("soon", "--start 'soon': expected seconds from the log's start (12.5) or an ISO 8601"),
        ("inf", "--start 'inf': expected seconds"),
        ("2025-13-01T00:00:00Z", "--start '2025-13-01T00:00:00Z': expected seconds"),
    ],
)
def test_bad_times_are_usage_errors(text: str, message: str) -> None:
    with pytest.raises(UsageError) as err:
        parse_time(text, "--start")
    assert str(err.value).startswith(message)


@pytest.mark.parametrize(
    ("start", "end"),
    [("10", "10"), ("10", "5"), ("2025-04-08T14:34:31Z", "2025-04-08T14:34:30Z")],
)
def test_start_must_be_before_end(start: str, end: str) -> None:
    with pytest.raises(UsageError, match=f"--start {start} is not before --end {end}"):
        Selection.parse((), start, end)


def test_start_and_end_of_different_kinds_are_ordered_once_the_log_is_known() -> None:
    log = make_log(t0_ns=APRIL_8)
    selection = Selection.parse((), "5", "2025-04-08T14:34:33Z")  # 5 s after, 3 s after
    with pytest.raises(UsageError, match="is not before --end"):
        apply_selection(log, selection, None)


def test_window_is_half_open_and_keeps_the_poses_around_it() -> None:
    log = make_log()
    cut = select_window(log, 2 * S + S // 2, 5 * S + S // 2)
    # readings at 2.5, 3.5, 4.5 s; not the one at 5.5 s (the end is not included)
    assert sorted(set(cut.readings.stamp_ns.tolist())) == [
        2 * S + S // 2,
        3 * S + S // 2,
        4 * S + S // 2,
    ]
    assert cut.poses.stamp_ns.tolist() == [2 * S, 3 * S, 4 * S, 5 * S, 6 * S]
    assert cut.truth is not None and cut.truth.stamp_ns.tolist() == cut.poses.stamp_ns.tolist()
    assert cut.sensor_names == log.sensor_names


def test_window_between_poses_keeps_the_bracketing_ones() -> None:
    log = make_log()
    cut = select_window(log, 3 * S + S // 4, 3 * S + 3 * S // 4)
    assert cut.poses.stamp_ns.tolist() == [3 * S, 4 * S]
    assert len(cut.readings) == len(log.sensor_names)


def test_open_ended_windows() -> None:
    log = make_log()
    whole = select_window(log, None, None)
    assert named(whole) == named(log) and len(whole.poses) == len(log.poses)
    tail = select_window(log, 8 * S, None)
    assert tail.poses.stamp_ns.tolist() == [8 * S, 9 * S, 10 * S]
    head = select_window(log, None, S)
    assert head.poses.stamp_ns.tolist() == [0, S] and len(head.readings) == 5


def test_seconds_count_from_the_first_pose_or_reading() -> None:
    log = make_log(t0_ns=100 * S)
    early = dataclasses.replace(
        log,
        readings=RangeReadings(
            np.concatenate([[99 * S], log.readings.stamp_ns]),
            np.concatenate([[0], log.readings.sensor]).astype(np.int32),
            np.concatenate([[1.0], log.readings.range_m]),
        ),
    )
    for data, origin in ((log, 100 * S), (early, 99 * S)):
        selected = apply_selection(data, Selection.parse((), "2", "3"), None)
        assert (selected.start_ns, selected.end_ns) == (origin + 2 * S, origin + 3 * S)


def test_iso_window_on_a_clock_stamped_log() -> None:
    log = make_log(t0_ns=APRIL_8)
    selection = Selection.parse((), "2025-04-08T14:34:32Z", "2025-04-08T14:34:34.000000001")
    cut = apply_selection(log, selection, None).log
    assert sorted(set(cut.readings.stamp_ns.tolist())) == [
        APRIL_8 + 2_500_000_000,
        APRIL_8 + 3_500_000_000,
    ]


def test_iso_window_on_a_log_without_clock_times() -> None:
    with pytest.raises(UsageError) as err:
        apply_selection(make_log(), Selection.parse((), "2025-04-08T14:34:32Z", None), None)
    assert str(err.value) == (
        "--start 2025-04-08T14:34:32Z: run.log is not stamped with clock times (it spans "
        "0.000 s to 10.000 s (10.0 s)); give seconds from its start"
    )


def test_a_window_without_readings_names_the_log_span() -> None:
    log = make_log(t0_ns=APRIL_8)
    with pytest.raises(UsageError) as err:
        apply_selection(log, Selection.parse((), "60", "70"), None)
    assert str(err.value) == (
        "run.log: no range readings from 2025-04-08 14:35:30.000 UTC to 2025-04-08 14:35:40.000 "
        "UTC (--start 60 --end 70); the log spans 2025-04-08 14:34:30.000 UTC to "
        "14:34:40.000 UTC (10.0 s)"
    )


def test_calibrate_may_have_a_window_without_readings() -> None:
    log = make_log()
    cut = apply_selection(log, Selection.parse((), "60", None), None, need_readings=False).log
    assert len(cut.readings) == 0 and cut.poses.stamp_ns.tolist() == [10 * S]


@given(st.lists(st.integers(0, 11 * S), min_size=1, max_size=4, unique=True))
def test_consecutive_windows_share_out_every_reading_once(cuts: list[int]) -> None:
    log = make_log()
    edges: list[int | None] = [None, *sorted(cuts), None]
    parts = [
        select_window(log, lo, hi, need_readings=False) for lo, hi in itertools.pairwise(edges)
    ]
    stamps = np.concatenate([p.readings.stamp_ns for p in parts])
    assert stamps.tolist() == log.readings.stamp_ns.tolist()


# ---------------------------------------------------------------------------------- sensors


@pytest.mark.parametrize(
    ("patterns", "kept"),
    [
        (("laser_*",), ("laser_0", "laser_1", "laser_2")),
        (("sonar1", "laser_2"), ("sonar1", "laser_2")),  # union, in the log's order
        (("laser_[01]", "laser_*"), ("laser_0", "laser_1", "laser_2")),
        (("!sonar*",), ("laser_0", "laser_1", "laser_2")),  # only excludes: all but these
        (("!sonar0", "!laser_1"), ("sonar1", "laser_0", "laser_2")),
        (("laser_*", "!laser_1"), ("laser_0", "laser_2")),
        (("?onar0",), ("sonar0",)),
    ],
)
def test_patterns_choose_sensors(patterns: tuple[str, ...], kept: tuple[str, ...]) -> None:
    log = make_log()
    cut = select_sensors(log, patterns)
    assert cut.sensor_names == kept
    assert named(cut) == [(n, r) for n, r in named(log) if n in kept]
    assert cut.readings.sensor.dtype == np.int32
    assert cut.sensors == (tuple(s for s in log.sensors or () if s.name in kept) or ())


def test_patterns_are_case_sensitive() -> None:
    with pytest.raises(UsageError, match="'SONAR0' matches no sensor"):
        select_sensors(make_log(), ("SONAR0",))


def test_a_pattern_matching_nothing_lists_the_sensors_shortened() -> None:
    log = make_log(names=(*(f"laser_{i}" for i in range(180)), "sonar0", "sonar1"))
    with pytest.raises(UsageError) as err:
        select_sensors(log, ("laser*", "sonar_*", "!bumper"))
    assert str(err.value) == (
        "--sensors 'sonar_*', '!bumper' match no sensor of run.log "
        "(it has laser_0..laser_179, sonar0, sonar1)"
    )


def test_patterns_leaving_nothing() -> None:
    with pytest.raises(UsageError, match=r"--sensors 'sonar\*' '!sonar\*' leave no sensor"):
        select_sensors(make_log(), ("sonar*", "!sonar*"))


def test_empty_pattern() -> None:
    with pytest.raises(UsageError, match="--sensors '!': an empty pattern matches no sensor"):
        Selection.parse(("!",), None, None)


def test_a_selected_log_is_the_log_with_only_those_sensors() -> None:
    full = make_log()
    only = make_log(names=("sonar1", "laser_1"))
    cut = keep_sensors(full, ["laser_1", "sonar1"])
    assert cut.sensor_names == only.sensor_names
    assert cut.sensors == only.sensors
    np.testing.assert_array_equal(cut.readings.stamp_ns, only.readings.stamp_ns)
    np.testing.assert_array_equal(cut.readings.sensor, only.readings.sensor)
    # ranges tell the original sensor: 2.0 (sonar1) and 4.0 (laser_1)
    assert sorted(set(cut.readings.range_m.tolist())) == [2.0, 4.0]


@pytest.mark.parametrize(
    ("names", "text"),
    [
        ((), ""),
        (("a",), "a"),
        (("sonar0", "sonar1"), "sonar0, sonar1"),
        (tuple(f"sonar{i}" for i in range(16)), "sonar0..sonar15"),
        (("l_0", "l_1", "l_2", "l_4", "x"), "l_0..l_2, l_4, x"),
        (("l_2", "l_1", "l_0"), "l_2, l_1, l_0"),
        (
            tuple(f"s{i}" for i in range(0, 40, 2)),
            ", ".join(f"s{i}" for i in range(0, 24, 2)) + " and 8 more",
        ),
    ],
)
def test_names_text(names: tuple[str, ...], text: str) -> None:
    assert names_text(names) == text


# ------------------------------------------------------------------------- other columns

CSV = "time,x,y,theta,sonar0,battery_v,sonar1\n0,0,0,0,1.5,12.6,2.5\n0.1,0,0,0,1.5,12.5,\n"


def test_columns_the_robot_lacks_are_left_out_with_one_note() -> None:
    log = read_csv_log(io.StringIO(CSV), name="run.csv")
    cut, notes = ignore_other_columns(log, load_robot("p3at"))
    assert cut.sensor_names == ("sonar0", "sonar1")
    assert named(cut) == [("sonar0", 1.5), ("sonar1", 2.5), ("sonar0", 1.5)]
    assert notes == ("run.csv: column 'battery_v' is not a range sensor of robot 'p3at'; ignored",)


def test_many_other_columns_make_one_note() -> None:
    extra = [f"aux{i}" for i in range(7)]
    text = "time,x,y,theta,sonar0," + ",".join(extra) + "\n0,0,0,0,1," + ",".join("1" * 7) + "\n"
    _, notes = ignore_other_columns(read_csv_log(io.StringIO(text), "r.csv"), load_robot("p3dx"))
    assert notes == (
        "r.csv: columns 'aux0', 'aux1', 'aux2', 'aux3', 'aux4' and 2 more are not range sensors "
        "of robot 'p3dx'; ignored",
    )


def test_other_columns_need_a_robot_to_judge_and_a_column_log() -> None:
    log = read_csv_log(io.StringIO(CSV), name="run.csv")
    same, notes = ignore_other_columns(log, None)
    assert same is log and notes == ()
    not_columns = dataclasses.replace(log, names_are_columns=False)  # ARIA, MCAP: sensors
    same, notes = ignore_other_columns(not_columns, load_robot("p3at"))
    assert same is not_columns and notes == ()


def test_selection_runs_before_the_column_note() -> None:
    """Choosing sensors first means a column left out by --sensors needs no warning."""
    log = read_csv_log(io.StringIO(CSV), name="run.csv")
    robot = load_robot("p3at")
    assert apply_selection(log, Selection.parse(("sonar*",), None, None), robot).notes == ()
    assert apply_selection(log, Selection.parse(("!battery_v",), None, None), robot).notes == ()
    assert len(apply_selection(log, Selection(), robot).notes) == 1
