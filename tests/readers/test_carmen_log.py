"""The CARMEN reader on tiny logs written inline: every message kind, quirk and broken line."""

from __future__ import annotations

import gzip
import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.errors import InputFileError, UnknownFormatError
from gridmap_cli.readers import read_log, resolve_format
from gridmap_cli.readers.text.carmen_log import read_carmen_log
from tests.readers.carmen_helpers import (
    flaser,
    odom,
    rawlaser,
    robotlaser,
    truepos,
    write,
)

RANGES = [1.0, 2.0, 3.0, 2.0, 1.0]


def corrected_log() -> list[str]:
    """Drive 0.2 m per ODOM along x; the SLAM correction moves each scan 0.05 m to the left."""
    return [
        odom((0.0, 0.0, 0.0), 1.0),
        odom((0.2, 0.0, 0.0), 1.2),
        odom((0.4, 0.0, 0.0), 1.4),
        flaser(RANGES, (0.4, 0.05, 0.0), 1.4),
        "NEFF 30",
        odom((0.4, 0.05, 0.0), 0.0),  # restart at the corrected pose, stamp 0
        odom((0.6, 0.05, 0.0), 1.6),
        odom((0.8, 0.05, 0.1), 1.8),
        flaser(RANGES, (0.8, 0.10, 0.1), 1.8),
        odom((0.8, 0.10, 0.1), 0.0),
        odom((0.8 + 0.2 * math.cos(0.1), 0.10 + 0.2 * math.sin(0.1), 0.1), 2.0),
    ]


def test_corrected_log_gives_raw_odometry_and_corrected_truth(tmp_path: Path) -> None:
    log = read_carmen_log(write(tmp_path, corrected_log()))
    p = log.poses
    # ODOM lines (restarts left out) and one pose at each scan's stamp, 1 us after its ODOM
    s = 1_000_000_000
    np.testing.assert_array_equal(
        p.stamp_ns,
        [1 * s, 1.2 * s, 1.4 * s, 1.4 * s + 1000, 1.6 * s, 1.8 * s, 1.8 * s + 1000, 2 * s],
    )
    # the raw odometry never sees the corrections: 0.2 m steps, a 0.1 rad turn
    np.testing.assert_allclose(p.x_m[:6], [0.0, 0.2, 0.4, 0.4, 0.6, 0.8], atol=1e-9)
    np.testing.assert_allclose(p.y_m[:6], 0.0, atol=1e-9)
    np.testing.assert_allclose(p.theta_rad[5:], 0.1, atol=1e-9)
    np.testing.assert_allclose(p.x_m[-1], 0.8 + 0.2 * math.cos(0.1), atol=1e-9)
    np.testing.assert_allclose(p.y_m[-1], 0.2 * math.sin(0.1), atol=1e-9)
    assert log.truth is not None
    np.testing.assert_array_equal(log.truth.stamp_ns, [1.4 * s + 1000, 1.8 * s + 1000])
    np.testing.assert_allclose(log.truth.y_m, [0.05, 0.10])
    assert "corrected log" in log.metadata["carmen"]
    assert log.metadata["skipped"] == "NEFF 1"


def test_flaser_beams_span_from_minus_90_degrees(tmp_path: Path) -> None:
    log = read_carmen_log(write(tmp_path, corrected_log()))
    assert log.sensor_names == tuple(f"frontlaser_{i}" for i in range(5))
    assert log.sensors is not None
    yaws = [math.degrees(s.yaw_rad) for s in log.sensors]
    np.testing.assert_allclose(yaws, [-90, -45, 0, 45, 90])  # 5 beams: 180 deg over 4 gaps
    assert {s.kind for s in log.sensors} == {"laser"}
    assert log.sensors[0].max_range_m == 80.0
    np.testing.assert_allclose(log.readings.range_m, RANGES * 2)
    assert log.readings.stamp_ns[0] == log.poses.stamp_ns[3]


def test_180_beams_are_one_degree_apart(tmp_path: Path) -> None:
    log = read_carmen_log(
        write(tmp_path, [odom((0, 0, 0), 1.0), flaser([1.0] * 180, (0, 0, 0), 1.0)])
    )
    assert log.sensors is not None and len(log.sensors) == 180
    assert math.degrees(log.sensors[0].yaw_rad) == pytest.approx(-90)
    assert math.degrees(log.sensors[-1].yaw_rad) == pytest.approx(89)


def test_params_mount_the_laser_and_cap_its_range(tmp_path: Path) -> None:
    header = (
        "PARAM robot_frontlaser_offset 0.25 1.0 host 1.0\n"
        "PARAM robot_front_laser_max 2.5 1.0 host 1.0\n"
        "PARAM laser_front_laser_resolution 0.5 nohost 0\n"
    )
    lines = [odom((0, 0, 0), 1.0), flaser([1.0, 2.0, 3.0, 2.5, 0.0], (0, 0, 0), 1.0)]
    log = read_carmen_log(write(tmp_path, lines, header=header))
    assert log.sensors is not None
    assert log.sensors[0].x_m == 0.25 and log.sensors[0].max_range_m == 2.5
    assert math.degrees(log.sensors[1].yaw_rad - log.sensors[0].yaw_rad) == pytest.approx(0.5)
    # 3.0 and 2.5 are at or beyond the maximum: no echo (inf); 0 is no reading: left out
    np.testing.assert_allclose(log.readings.range_m, [1.0, 2.0, math.inf, math.inf])
    assert (
        "(PARAM robot_front_laser_max); 2 readings at or beyond it: no echo"
        in log.metadata["frontlaser"]
    )


def test_a_repeated_largest_reading_is_the_no_echo_value(tmp_path: Path) -> None:
    lines = [odom((0, 0, 0), 1.0)]
    lines += [flaser([50.0, 3.0, 50.0], (0, 0, 0), 1.0 + 0.1 * i) for i in range(6)]
    log = read_carmen_log(write(tmp_path, lines))
    assert log.sensors is not None and log.sensors[0].max_range_m == 50.0
    np.testing.assert_allclose(log.readings.range_m, [math.inf, 3.0, math.inf] * 6)


def test_rear_laser_faces_backward_behind_the_centre(tmp_path: Path) -> None:
    header = "PARAM robot_rearlaser_offset 0.1 nohost 0\n"
    lines = [odom((0, 0, 0), 1.0), flaser(RANGES, (0, 0, 0), 1.0, "RLASER")]
    log = read_carmen_log(write(tmp_path, lines, header=header))
    assert log.sensors is not None and log.sensor_names[0] == "rearlaser_0"
    rear = log.sensors[2]  # the middle beam points along the laser's axis
    assert rear.x_m == -0.1 and rear.yaw_rad == pytest.approx(math.pi)


def test_robotlaser_layout_comes_from_the_message_and_rawlaser_duplicates_are_skipped(
    tmp_path: Path,
) -> None:
    lines = [
        odom((0, 0, 0), 1.0),
        rawlaser([1.0, 2.0, 3.0], 1.05),
        robotlaser([1.0, 2.0, 3.0], (0, 0, 0), 1.05, start=-0.5, res=0.25, max_range=8.0),
        odom((0.1, 0, 0), 1.1),
    ]
    log = read_carmen_log(write(tmp_path, lines))
    assert log.sensors is not None and len(log.sensors) == 3
    np.testing.assert_allclose([s.yaw_rad for s in log.sensors], [-0.5, -0.25, 0.0])
    assert log.sensors[0].max_range_m == 8.0
    assert len(log.readings) == 3
    assert log.metadata["skipped"] == "RAWLASER1 1 (same laser as ROBOTLASER)"
    assert log.truth is None  # a raw log: its laser poses are odometry


def test_old_robotlaser_without_remission_mode(tmp_path: Path) -> None:
    line = robotlaser([1.5, 2.5], (0, 0, 0), 1.0).replace(" 0.01 0 2 ", " 0.01 2 ", 1)
    log = read_carmen_log(write(tmp_path, [odom((0, 0, 0), 0.5), line]))
    np.testing.assert_allclose(log.readings.range_m, [1.5, 2.5])


def test_rawlaser_alone_is_placed_by_the_odometry(tmp_path: Path) -> None:
    lines = [odom((0, 0, 0), 1.0), rawlaser([1.0, 2.0], 1.5, number=3), odom((1, 0, 0), 2.0)]
    log = read_carmen_log(write(tmp_path, lines))
    assert log.sensor_names == ("laser3_0", "laser3_1")
    assert log.sensors is not None and log.sensors[0].x_m == 0.0


def test_truepos_is_the_truth(tmp_path: Path) -> None:
    lines = [
        odom((0, 0, 0), 1.0),
        truepos((5.0, 5.0, 1.0), (0, 0, 0), 1.0),
        flaser(RANGES, (0, 0, 0), 1.2),
        odom((0.1, 0, 0), 2.0),
        truepos((5.1, 5.0, 1.0), (0.1, 0, 0), 2.0),
    ]
    log = read_carmen_log(write(tmp_path, lines))
    assert log.truth is not None and len(log.truth) == 2
    np.testing.assert_allclose(log.truth.x_m, [5.0, 5.1])
    assert "TRUEPOS" in log.metadata["truth"]


def test_no_odom_lines_use_the_laser_poses(tmp_path: Path) -> None:
    lines = [flaser(RANGES, (0, 0, 0), 1.0), flaser(RANGES, (1, 0, 0), 2.0)]
    log = read_carmen_log(write(tmp_path, lines))
    np.testing.assert_allclose(log.poses.x_m, [0.0, 1.0])
    assert log.metadata["odometry"].startswith("no ODOM lines")


def test_unknown_messages_sync_and_comments_are_skipped(tmp_path: Path) -> None:
    lines = [
        "SYNC start",
        "GPSNMEA 1 2 3 host 4",
        "# a comment",
        "",
        odom((0, 0, 0), 1.0),
        flaser(RANGES, (0, 0, 0), 1.0),
    ]
    log = read_carmen_log(write(tmp_path, lines))
    assert log.metadata["skipped"] == "GPSNMEA 1, SYNC 1"


def test_gzip_log_reads_like_the_plain_one_and_errors_name_its_lines(tmp_path: Path) -> None:
    plain = write(tmp_path, corrected_log())
    packed = tmp_path / "run.log.gz"
    packed.write_bytes(gzip.compress(plain.read_bytes()))
    a, b = read_log(plain), read_log(packed)
    np.testing.assert_array_equal(a.poses.x_m, b.poses.x_m)
    np.testing.assert_array_equal(a.readings.range_m, b.readings.range_m)
    assert b.source == str(packed)
    broken = plain.read_text().replace("ODOM 0.600000000", "ODOM zero", 1)
    packed.write_bytes(gzip.compress(broken.encode()))
    with pytest.raises(InputFileError) as err:
        read_log(packed)
    assert str(err.value) == f"{packed}:10: ODOM: pose x: not a number: 'zero'"


def test_registry_resolution(tmp_path: Path) -> None:
    lines = corrected_log()
    assert resolve_format(write(tmp_path, lines, "a.log")).name == "carmen"
    assert resolve_format(write(tmp_path, lines, "a.clf")).name == "carmen"
    assert resolve_format(write(tmp_path, lines, "a.txt")).name == "carmen"  # sniffed
    gz = tmp_path / "b.gz"  # no inner extension: sniffed after decompressing
    gz.write_bytes(gzip.compress(write(tmp_path, lines).read_bytes()))
    assert resolve_format(gz).name == "carmen"
    # a .log that is nothing is still the CARMEN reader's to refuse, with a line
    other = tmp_path / "other.log"
    other.write_text("hello world\n")
    with pytest.raises(InputFileError, match=r"other.log:1: not a CARMEN message line"):
        read_log(other)
    with pytest.raises(UnknownFormatError):
        resolve_format(write(tmp_path, ["hello"], "c.txt", header=""))


def test_corrupt_gzip_is_one_line_error(tmp_path: Path) -> None:
    good = gzip.compress(write(tmp_path, corrected_log()).read_bytes())
    truncated = tmp_path / "t.log.gz"
    truncated.write_bytes(good[: len(good) // 2])
    with pytest.raises(InputFileError, match=r"t.log.gz: not a valid gzip file: .*truncated"):
        read_log(truncated)
    garbage = tmp_path / "g.log.gz"
    garbage.write_bytes(b"this is not gzip at all")
    with pytest.raises(InputFileError, match=r"^\S*g.log.gz: not a valid gzip file"):
        read_log(garbage)
    mcap = tmp_path / "m.mcap.gz"
    mcap.write_bytes(gzip.compress(b"\x89MCAP0\r\n"))
    with pytest.raises(InputFileError, match="gzip-compressed mcap logs are not supported"):
        read_log(mcap)


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("ODOM 1 2 3 0 0 0 1.0 host", "ODOM: expected 10 fields (x y theta tv rv accel "
         "ipc_timestamp hostname logger_timestamp), found 9 (truncated line?)"),
        ("ODOM 1 two 3 0 0 0 1.0 host 1.0", "ODOM: pose y: not a number: 'two'"),
        ("ODOM 1 2 nan 0 0 0 1.0 host 1.0", "ODOM: pose theta: not a finite number: 'nan'"),
        ("ODOM 1 2 3 0 0 0 soon host 1.0", "ODOM: ipc_timestamp: not a number: 'soon'"),
        ("ODOM 1 2 3 0 0 0 1e300 host 1.0", "ODOM: ipc_timestamp: '1e300' s is beyond what a "
         "nanosecond stamp holds (about 292 years from zero)"),
        ("FLASER 3 1 2 0 0 0 0 0 0 1.0 host 1.0", "FLASER: num_readings 3 means 14 fields "
         "(ranges, laser and robot pose, ipc_timestamp hostname logger_timestamp), found 13"),
        ("FLASER three 1 2 3", "FLASER: num_readings: not a whole number: 'three'"),
        ("FLASER 2 1 -2 0 0 0 0 0 0 1.0 host 1.0", "FLASER: negative range -2"),
        ("FLASER 2 1 x 0 0 0 0 0 0 1.0 host 1.0", "FLASER: range: not a number: 'x'"),
        ("TRUEPOS 1 2 3 4 5 6 1.0 host", "TRUEPOS: expected 10 fields"),
        ("ROBOTLASER1 0 -1.57 3.14 0.0175 80 0.01 0 3 1 2 3 0 0 0 0 0 0 0 1.0 host 1.0",
         "ROBOTLASER1: num_readings 3 and num_remissions 0 mean 27 fields, found 22"),
        ("PARAM lonely", "PARAM: expected a name and a value"),
        ("1.0 2.0 3.0", "not a CARMEN message line: '1.0 2.0 3.0'"),
    ],
)  # fmt: skip
def test_malformed_lines_name_file_and_line(tmp_path: Path, line: str, message: str) -> None:
    path = write(tmp_path, [odom((0, 0, 0), 0.5), line, flaser(RANGES, (0, 0, 0), 1.0)])
    with pytest.raises(InputFileError) as err:
        read_carmen_log(path)
    assert str(err.value).startswith(f"{path}:5: {message}")


def test_bad_param_value_is_reported_where_it_is(tmp_path: Path) -> None:
    header = "PARAM robot_frontlaser_offset front nohost 0\n"
    path = write(tmp_path, [odom((0, 0, 0), 1.0), flaser(RANGES, (0, 0, 0), 1.0)], header=header)
    with pytest.raises(InputFileError, match=r":1: PARAM: robot_frontlaser_offset: not a number"):
        read_carmen_log(path)


def test_each_scan_keeps_its_own_layout(tmp_path: Path) -> None:
    """A laser interleaving start angles, or adding a beam: each direction is a beam sensor,
    the first scan's first; a direction seen before is its sensor again."""
    lines = [
        odom((0, 0, 0), 1.0),
        robotlaser([1.0, 2.0, 3.0], (0, 0, 0), 1.05, start=-0.5, res=0.25),
        robotlaser([4.0, 5.0, 6.0], (0, 0, 0), 1.10, start=-0.375, res=0.25),
        robotlaser([7.0, 8.0, 9.0, 10.0], (0, 0, 0), 1.15, start=-0.5, res=0.25),
        odom((0.1, 0, 0), 1.2),
    ]
    log = read_carmen_log(write(tmp_path, lines))
    assert log.sensors is not None
    yaws = [s.yaw_rad for s in log.sensors]
    np.testing.assert_allclose(yaws, [-0.5, -0.25, 0.0, -0.375, -0.125, 0.125, 0.25])
    assert log.readings.sensor.tolist() == [0, 1, 2, 3, 4, 5, 0, 1, 2, 6]
    assert log.readings.range_m.tolist() == [float(v) for v in range(1, 11)]
    assert "(and 2 other layouts: 7 directions)" in log.metadata["frontlaser"]


def test_empty_log_and_log_without_laser(tmp_path: Path) -> None:
    empty = write(tmp_path, [], "empty.log", header="")
    with pytest.raises(InputFileError, match=r"empty.log: no CARMEN messages in the log"):
        read_carmen_log(empty)
    no_laser = write(tmp_path, [odom((0, 0, 0), 1.0), odom((1, 0, 0), 2.0)], "odom.log")
    with pytest.raises(InputFileError, match=r"odom.log:5: no laser lines .*nothing to map"):
        read_carmen_log(no_laser)
