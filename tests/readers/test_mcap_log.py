"""The MCAP reader on small recordings written in the tests (ROS 1, ROS 2, gridmap JSON)."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from mcap.reader import SeekingReader
from mcap.writer import IndexType, Writer

from gridmap_cli.errors import InputFileError, UsageError
from gridmap_cli.readers import read_log, resolve_format
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros.mcap.channels import survey_mcap
from gridmap_cli.readers.ros.mcap.log import float32_decimal, read_mcap, read_mcap_log
from gridmap_cli.robot import load_robot
from tests.helpers import names, run
from tests.readers.mcap_helpers import (
    Recording,
    S,
    drive,
    odometry,
    one_sonar_log,
    sonar_range,
    static_tf,
    turn,
)


def ros2_sonar_messages(rec: Recording) -> None:
    """A sonar mounted through an intermediate frame, readings of every kind."""
    static_tf(
        rec,
        rec.transform(0, "base_link", "ring", 0.1, 0.0, 0.0),
        rec.transform(0, "ring", "sonar_left", 0.0, 0.2, math.pi / 2),
    )
    drive(rec)
    values = [1.0, 3.0, math.inf, math.nan, 0.05, -math.inf, 2.5]
    for k, value in enumerate(values):
        ns = S + (k + 1) * S // 10
        rec.write("/sonar", "sensor_msgs/Range", ns, sonar_range(rec, ns, "sonar_left", value))


def ros2_sonar_log(path: Path) -> Path:
    """ROS 2: :func:`ros2_sonar_messages`."""
    with Recording(path) as rec:
        ros2_sonar_messages(rec)
    return path


def test_ros2_range_readings_mounting_through_tf_and_no_echo(tmp_path: Path) -> None:
    log = read_mcap_log(ros2_sonar_log(tmp_path / "run.mcap"))
    assert len(log.poses) == 11
    assert log.poses.x_m.tolist() == pytest.approx([0.1 * k for k in range(11)])
    assert log.sensor_names == ("sonar_left",)
    assert log.sensors is not None
    s = log.sensors[0]
    assert (s.x_m, s.y_m, s.yaw_rad) == pytest.approx((0.1, 0.2, math.pi / 2))
    assert (s.beam_width_rad, s.min_range_m, s.max_range_m) == pytest.approx((0.5, 0.1, 3.0))
    # NaN: no reading; -inf: too close (dropped); 3.0 (= max) and +inf: no echo = 3.0;
    # 0.05 < min_range is kept for the sync stage to count and drop
    assert log.readings.range_m.tolist() == pytest.approx([1.0, 3.0, 3.0, 0.05, 2.5])
    assert log.readings.stamp_ns.tolist() == [S + k * S // 10 for k in (1, 2, 3, 5, 7)]


def test_build_from_ros2_mcap_writes_a_map(tmp_path: Path) -> None:
    log = ros2_sonar_log(tmp_path / "run.mcap")
    code, out, err = run("build", str(log), "-o", str(tmp_path / "map.png"), "--json")
    assert code == 0, err
    summary = json.loads(out)
    assert summary["readings"]["total"] == 5
    assert summary["readings"]["below_min_range"] == 1
    assert summary["readings"]["used"] == 4
    assert (tmp_path / "map.yaml").is_file()


def test_extensionless_mcap_is_found_by_its_magic(tmp_path: Path) -> None:
    path = ros2_sonar_log(tmp_path / "recording")
    assert resolve_format(path).name == "mcap"
    assert len(read_log(path).readings) == 5


def test_two_odometry_topics_are_ambiguous_and_listed(tmp_path: Path) -> None:
    path = one_sonar_log(tmp_path / "two.mcap", odom_topics={"/wheel_odom": 11, "/visual_odom": 4})
    with pytest.raises(InputFileError) as err:
        read_log(path)
    assert str(err.value) == (
        f"{path}: more than one odometry topic: /wheel_odom (nav_msgs/Odometry, 11 messages); "
        "/visual_odom (nav_msgs/Odometry, 4 messages); choose one with --odom-topic"
    )
    chosen = read_log(path, options=ReadOptions(odom_topic="/visual_odom"))
    assert len(chosen.poses) == 4
    code, _, stderr = run("build", str(path), "-o", str(tmp_path / "m.png"), "--odom-topic", "/x")
    assert code == 2
    assert stderr.startswith(f"Error: {path}: --odom-topic /x: no such topic; topics: ")
    assert "/sonar (sensor_msgs/Range, 1 messages)" in stderr
    assert not (tmp_path / "m.png").exists()


def test_range_topic_flag_picks_topics_and_rejects_other_types(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    with Recording(path) as rec:
        static_tf(
            rec,
            rec.transform(0, "base_link", "front", 0.2, 0.0, 0.0),
            rec.transform(0, "base_link", "back", -0.2, 0.0, math.pi),
        )
        drive(rec)
        rec.write("/front", "sensor_msgs/Range", S, sonar_range(rec, S, "front", 1.0))
        rec.write("/back", "sensor_msgs/Range", S, sonar_range(rec, S, "back", 2.0))
    assert read_log(path).sensor_names == ("front", "back")  # tf_static order
    only = read_log(path, options=ReadOptions(range_topics=("/back",)))
    assert only.sensor_names == ("back",)
    assert only.readings.range_m.tolist() == [2.0]
    with pytest.raises(UsageError, match=r"--range-topic /odom is nav_msgs/Odometry, not a range"):
        read_log(path, options=ReadOptions(range_topics=("/odom",)))


def test_one_frame_on_two_topics_must_be_chosen(tmp_path: Path) -> None:
    path = one_sonar_log(tmp_path / "dup.mcap", topics=("/raw", "/filtered"))
    with pytest.raises(InputFileError, match=r"'s0' publishes on both /raw and /filtered"):
        read_log(path)


@pytest.mark.parametrize(
    ("frame", "mount", "why"),
    [
        ("sonar_b", ("base_link", "sonar_a"), "no transform from 'base_link' to it on /tf_static"),
        ("sonar_a", ("camera_rig", "sonar_a"),
         "its transforms lead to 'camera_rig', not to the base frame 'base_link' (--base-frame)"),
    ],
)  # fmt: skip
def test_unknown_mounting_says_what_is_missing_and_nothing_is_written(
    tmp_path: Path, frame: str, mount: tuple[str, str], why: str
) -> None:
    path = one_sonar_log(tmp_path / "nomount.mcap", frame=frame, mount=mount)
    message = (
        f"{path}: sensor frame '{frame}' (/sonar): mounting pose unknown: {why}, and no --robot "
        "describing it"
    )
    with pytest.raises(InputFileError) as err:
        read_log(path)
    assert str(err.value) == message
    code, _, stderr = run("build", str(path), "-o", str(tmp_path / "map.png"))
    assert (code, stderr.strip()) == (1, f"Error: {message}")
    assert names(tmp_path) == {"nomount.mcap"}


def test_range_limits_that_change_keep_the_largest_of_each(tmp_path: Path) -> None:
    path = tmp_path / "limits.mcap"
    with Recording(path) as rec:
        static_tf(rec, rec.transform(0, "base_link", "s0", 0.0, 0.0, 0.0))
        drive(rec)
        for k, (value, rmin, rmax) in enumerate(
            ((2.5, 0.1, 3.0), (2.5, 0.2, 2.0), (0.15, 0.2, 2.0))
        ):
            ns = S + k * S // 10
            rec.write("/sonar", "sensor_msgs/Range", ns,
                      sonar_range(rec, ns, "s0", value, rmin=rmin, rmax=rmax))  # fmt: skip
    log = read_log(path)
    assert log.sensors is not None
    assert (log.sensors[0].min_range_m, log.sensors[0].max_range_m) == (0.2, 3.0)
    # each reading is judged by its own message's limits: 2.5 >= 2.0 is no echo, stored at the
    # sensor's maximum; 0.15 is kept for sync, which drops it below the sensor's 0.2
    assert log.readings.range_m.tolist() == [2.5, 3.0, 0.15]


def test_robot_description_mounts_sensors_the_tf_lacks(tmp_path: Path) -> None:
    path = one_sonar_log(tmp_path / "robot.mcap", frame="sonar3", mount=None)
    p3at = load_robot("p3at")
    log = read_log(path, options=ReadOptions(robot=p3at))
    assert log.sensors is not None
    mount = p3at.by_name()["sonar3"]
    assert (log.sensors[0].x_m, log.sensors[0].yaw_rad) == (mount.x_m, mount.yaw_rad)
    assert log.sensors[0].beam_width_rad == pytest.approx(0.5)  # the beam is the message's


def test_ros1_leading_slashes_tf_odometry_and_mounts_from_tf(tmp_path: Path) -> None:
    # a ROS 1 bag: no /tf_static, no Odometry topic; '/odom' -> '/base_link' and the sonar
    # mount both on /tf, with the old leading-slash frame ids
    path = tmp_path / "ros1.mcap"
    with Recording(path, ros=1) as rec:
        for k in range(5):
            ns = S + k * S // 10
            rec.write(
                "/tf",
                "tf/tfMessage",
                ns,
                {
                    "transforms": [
                        rec.transform(ns, "/odom", "/base_link", 0.5 * k, 0.0, 0.1 * k),
                        rec.transform(ns, "/base_link", "/sonar_front", 0.25, -0.05, 0.0),
                    ]
                },
            )
            rec.write(
                "/sonar", "sensor_msgs/Range", ns, sonar_range(rec, ns, "sonar_front", 1.0 + k)
            )
    log = read_log(path)
    assert log.poses.x_m.tolist() == pytest.approx([0.0, 0.5, 1.0, 1.5, 2.0])
    assert log.poses.theta_rad.tolist() == pytest.approx([0.0, 0.1, 0.2, 0.3, 0.4])
    assert log.sensor_names == ("sonar_front",)
    assert log.sensors is not None
    assert (log.sensors[0].x_m, log.sensors[0].y_m) == pytest.approx((0.25, -0.05))
    assert log.readings.range_m.tolist() == pytest.approx([1.0, 2.0, 3.0, 3.0, 3.0])


def test_tf_odometry_with_other_frame_names(tmp_path: Path) -> None:
    path = tmp_path / "frames.mcap"
    with Recording(path, ros=1) as rec:
        for k in range(3):
            ns = S + k * S
            tfs = [
                rec.transform(ns, "world_odom", "chassis", float(k), 0.0, 0.0),
                rec.transform(ns, "world_odom", "trailer", -float(k), 0.0, 0.0),
                rec.transform(ns, "chassis", "s0", 0.0, 0.0, 0.0),
            ]
            rec.write("/tf", "tf/tfMessage", ns, {"transforms": tfs})
            rec.write("/sonar", "sensor_msgs/Range", ns, sonar_range(rec, ns, "s0", 1.0))
    with pytest.raises(InputFileError, match=r"no 'odom' -> 'base_link' transform on /tf"):
        read_log(path)
    opts = ReadOptions(odom_frame="world_odom", base_frame="/chassis")
    assert read_log(path, options=opts).poses.x_m.tolist() == [0.0, 1.0, 2.0]


def test_rosaria_pointcloud_sonar_ranges_from_robot_geometry(tmp_path: Path) -> None:
    # RosAria: one point per sonar, the echo's position in the robot frame (metres)
    p3at = load_robot("p3at")
    sonars = [s for s in p3at.sensors if s.kind == "sonar"]
    truth = [0.5 + 0.1 * i for i in range(len(sonars))]
    path = tmp_path / "rosaria.mcap"
    with Recording(path, ros=1) as rec:
        drive(rec)
        points = [
            {
                "x": s.x_m + r * math.cos(s.yaw_rad),
                "y": s.y_m + r * math.sin(s.yaw_rad),
                "z": 0.0,
            }
            for s, r in zip(sonars, truth, strict=True)
        ]
        rec.write(
            "/RosAria/sonar",
            "sensor_msgs/PointCloud",
            S,
            {"header": rec.header(S, "sonar"), "points": points},
        )
    with pytest.raises(InputFileError, match=r"/RosAria/sonar: sonar point clouds .* --robot"):
        read_log(path)
    log = read_log(path, options=ReadOptions(robot=p3at))
    assert log.sensor_names == tuple(s.name for s in sonars)
    assert log.readings.sensor.tolist() == list(range(len(sonars)))
    assert log.readings.range_m.tolist() == pytest.approx(truth, abs=1e-6)  # float32 points


def test_pointcloud_in_a_frame_of_its_own_is_moved_into_the_base_frame(tmp_path: Path) -> None:
    # the same echoes as above, published in a frame 'ring' at (0.1, -0.05) turned 0.3 rad
    p3at = load_robot("p3at")
    sonars = [s for s in p3at.sensors if s.kind == "sonar"]
    truth = [0.5 + 0.1 * i for i in range(len(sonars))]
    tx, ty, yaw = 0.1, -0.05, 0.3
    points = []
    for s, r in zip(sonars, truth, strict=True):
        bx, by = s.x_m + r * math.cos(s.yaw_rad) - tx, s.y_m + r * math.sin(s.yaw_rad) - ty
        points.append({"x": math.cos(yaw) * bx + math.sin(yaw) * by,
                       "y": -math.sin(yaw) * bx + math.cos(yaw) * by, "z": 0.0})  # fmt: skip
    path = tmp_path / "ring.mcap"
    with Recording(path, ros=1) as rec:
        static_tf(rec, rec.transform(0, "base_link", "ring", tx, ty, yaw))
        drive(rec)
        rec.write("/RosAria/sonar", "sensor_msgs/PointCloud", S,
                  {"header": rec.header(S, "ring"), "points": points})  # fmt: skip
    log = read_log(path, options=ReadOptions(robot=p3at))
    assert log.readings.range_m.tolist() == pytest.approx(truth, abs=1e-6)


def test_laserscan_beams_take_the_frame_mount_and_scan_angles(tmp_path: Path) -> None:
    path = tmp_path / "scan.mcap"
    with Recording(path) as rec:
        static_tf(rec, rec.transform(0, "base_link", "laser", 0.15, 0.0, math.pi / 4))
        drive(rec)
        for k in range(2):
            ns = S + k * S // 2
            rec.write(
                "/scan",
                "sensor_msgs/LaserScan",
                ns,
                {
                    "header": rec.header(ns, "laser"),
                    "angle_min": -0.5,
                    "angle_max": 0.5,
                    "angle_increment": 0.5,
                    "range_min": 0.1,
                    "range_max": 8.0,
                    "ranges": [1.0, math.nan, math.inf],
                },
            )
    log = read_log(path)
    assert log.sensor_names == ("laser_0", "laser_1", "laser_2")
    assert log.sensors is not None
    yaws = [s.yaw_rad for s in log.sensors]
    assert yaws == pytest.approx([math.pi / 4 - 0.5, math.pi / 4, math.pi / 4 + 0.5])
    assert {(s.x_m, s.kind, s.beam_width_rad) for s in log.sensors} == {(0.15, "laser", 0.0)}
    assert log.readings.sensor.tolist() == [0, 2, 0, 2]
    assert log.readings.range_m.tolist() == [1.0, 8.0, 1.0, 8.0]


def test_laserscans_are_read_each_with_its_own_beams(tmp_path: Path) -> None:
    """A laser that interleaves start angles, or adds a beam, gives each direction a sensor:
    the first scan's beams, then the new directions, in order; a direction seen before is its
    sensor again."""
    path = tmp_path / "scan.mcap"
    geometries = [(-1.0, 3), (-1.25, 4), (-1.0, 4), (-1.25, 4)]
    with Recording(path) as rec:
        static_tf(rec, rec.transform(0, "base_link", "laser", 0.0, 0.0, 0.0))
        drive(rec)
        for k, (start, n) in enumerate(geometries):
            ns = S + k * S // 4
            scan = {"header": rec.header(ns, "laser"), "angle_min": start,
                    "angle_max": start + 0.5 * (n - 1), "angle_increment": 0.5,
                    "range_max": 8.0, "ranges": [1.0 + k] * n}  # fmt: skip
            rec.write("/scan", "sensor_msgs/LaserScan", ns, scan)
    log = read_log(path)
    assert log.sensor_names == tuple(f"laser_{i}" for i in range(8))
    assert log.sensors is not None
    yaws = [s.yaw_rad for s in log.sensors]
    assert yaws == pytest.approx([-1.0, -0.5, 0.0, -1.25, -0.75, -0.25, 0.25, 0.5])
    sensor, rng = log.readings.sensor.tolist(), log.readings.range_m.tolist()
    assert sensor == [0, 1, 2, 3, 4, 5, 6, 0, 1, 2, 7, 3, 4, 5, 6]
    assert rng == [1.0] * 3 + [2.0] * 4 + [3.0] * 4 + [4.0] * 4


def test_laserscan_whose_ranges_do_not_fit_its_angles_is_an_error(tmp_path: Path) -> None:
    path = tmp_path / "scan.mcap"
    with Recording(path) as rec:
        static_tf(rec, rec.transform(0, "base_link", "laser", 0.0, 0.0, 0.0))
        drive(rec)
        for k, n in enumerate((3, 5)):
            ns = S + k * S // 2
            scan = {"header": rec.header(ns, "laser"), "angle_min": -1.0, "angle_max": 0.0,
                    "angle_increment": 0.5, "range_max": 8.0, "ranges": [1.0] * n}  # fmt: skip
            rec.write("/scan", "sensor_msgs/LaserScan", ns, scan)
    with pytest.raises(InputFileError, match=r"/scan at log time 1.5.*laser 'laser': 5 ranges, "
                       r"but its angles do not fit them \(from -1 to 0 rad by 0.5"):  # fmt: skip
        read_log(path)


def test_unsorted_stamps_are_sorted_repeats_dropped_zero_stamps_use_log_time(
    tmp_path: Path,
) -> None:
    path = tmp_path / "unsorted.mcap"
    with Recording(path) as rec:
        static_tf(rec, rec.transform(0, "base_link", "s0", 0.0, 0.0, 0.0))
        # header stamps out of order (log times in order), one repeated
        for log_ns, stamp, x in ((S, 3 * S, 3.0), (2 * S, S, 1.0), (3 * S, 2 * S, 2.0),
                                 (4 * S, 2 * S, 9.0)):  # fmt: skip
            rec.write("/odom", "nav_msgs/Odometry", log_ns, odometry(rec, stamp, x, 0.0, 0.0))
        # a zero header stamp: the log time stands in
        rec.write("/sonar", "sensor_msgs/Range", int(2.5 * S), sonar_range(rec, 0, "s0", 1.0))
    log = read_log(path)
    assert log.poses.stamp_ns.tolist() == [S, 2 * S, 3 * S]
    assert log.poses.x_m.tolist() == [1.0, 2.0, 3.0]  # the first of the repeated stamp
    assert log.readings.stamp_ns.tolist() == [int(2.5 * S)]


def test_non_finite_pose_is_an_error_naming_topic_and_time(tmp_path: Path) -> None:
    path = tmp_path / "nan.mcap"
    with Recording(path) as rec:
        rec.write("/odom", "nav_msgs/Odometry", 2 * S, odometry(rec, 2 * S, math.nan, 0.0, 0.0))
        rec.write("/sonar", "sensor_msgs/Range", 2 * S, sonar_range(rec, 2 * S, "base_link", 1))
    with pytest.raises(InputFileError) as err:
        read_log(path)
    assert str(err.value) == (
        f"{path}: /odom at log time 2.000000000 s: pose is not finite (nan, 0.0, 0.0)"
    )


def test_absurd_coordinates_fail_the_build_cleanly(tmp_path: Path) -> None:
    path = tmp_path / "absurd.mcap"
    with Recording(path) as rec:
        for k, x in enumerate((0.0, 1e9)):
            ns = S + k * S
            rec.write("/odom", "nav_msgs/Odometry", ns, odometry(rec, ns, x, 0.0, 0.0))
            rec.write("/sonar", "sensor_msgs/Range", ns, sonar_range(rec, ns, "base_link", 1.0))
    code, _, err = run("build", str(path), "-o", str(tmp_path / "map.png"))
    assert code == 1
    # MapSizeError naming the log: x from the odometry, y the 1 m sonar cone (+-0.26 m) about x
    assert err.strip() == (
        f"Error: {path}: the data spans 1e+09 m x 0.519548 m (x 0..1e+09, y -0.259774..0.259774), "
        "20000000029 x 20 cells at 0.05 m: more than 100000000 cells; check the log for absurd "
        "coordinates or use a coarser --resolution"
    )
    assert names(tmp_path) == {"absurd.mcap"}


def _no_odometry(rec: Recording) -> None:
    rec.write("/sonar", "sensor_msgs/Range", S, sonar_range(rec, S, "s0", 1.0))


def _unmounted_sonar_and_laser(rec: Recording) -> None:
    drive(rec)
    rec.write("/sonar", "sensor_msgs/Range", S, sonar_range(rec, S, "s0", 1.0))
    scan = {"header": rec.header(S, "laser"), "angle_min": 0.0, "angle_max": 0.5,
            "angle_increment": 0.5, "range_max": 8.0, "ranges": [1.0, 2.0]}  # fmt: skip
    rec.write("/scan", "sensor_msgs/LaserScan", S, scan)


def _cloud_without_robot(rec: Recording) -> None:
    drive(rec)
    cloud = {"header": rec.header(S, "base_link"), "points": [{"x": 1.0, "y": 0.0, "z": 0.0}]}
    rec.write("/RosAria/sonar", "sensor_msgs/PointCloud", S, cloud)


@pytest.mark.parametrize(
    ("content", "error"),
    [
        (_no_odometry, "no odometry: no nav_msgs/Odometry, geometry_msgs/PoseStamped or "
                       "gridmap.Pose2D topic and no TF; topics: /sonar (sensor_msgs/Range, 1 "
                       "messages)"),
        (_unmounted_sonar_and_laser, "sensor frame 's0' (/sonar): mounting pose unknown: the "
                                     "recording has no TF, and no --robot describing it"),
        (_cloud_without_robot, "/RosAria/sonar: sonar point clouds (as RosAria publishes them) "
                               "need the sonar positions: give --robot (a preset, robot YAML or "
                               "ARIA .p file)"),
    ],
)  # fmt: skip
def test_lenient_read_keeps_the_first_error_the_strict_read_raises(
    tmp_path: Path, content: Callable[[Recording], None], error: str
) -> None:
    path = tmp_path / "broken.mcap"
    with Recording(path) as rec:
        content(rec)
    with pytest.raises(InputFileError) as err:
        read_mcap(path)
    assert str(err.value) == f"{path}: {error}"
    lenient = read_mcap(path, strict=False)
    assert str(lenient.problem) == str(err.value)
    # and reads on: whatever it could not place gets a NaN mounting
    for sensor in lenient.log.sensors or ():
        assert math.isnan(sensor.x_m)
    assert read_mcap(ros2_sonar_log(tmp_path / "fine.mcap"), strict=False).problem is None


def test_truncated_file_is_a_clear_error_and_writes_nothing(tmp_path: Path) -> None:
    whole = ros2_sonar_log(tmp_path / "whole.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(whole[: len(whole) // 2])
    code, _, err = run("build", str(cut), "-o", str(tmp_path / "map.png"))
    assert code == 1
    assert err.startswith(
        f"Error: {cut}: byte {len(whole) // 2}: truncated or damaged MCAP file: no valid footer"
    )
    assert "mcap recover" in err
    assert names(tmp_path) == {"whole.mcap", "cut.mcap"}


def test_topic_flags_are_refused_for_csv_logs(room_csv: Path, tmp_path: Path) -> None:
    code, _, err = run("build", str(room_csv), "-o", str(tmp_path / "m.png"), "--range-topic", "x")
    assert code == 2
    assert (
        err.strip()
        == "Error: --range-topic only applies to ROS recordings (MCAP, bag, rosbag2), not to CSV "
        "logs"
    )


# ---------------------------------------------------------------- gridmap JSON channels


def write_json_log(path: Path, truth: bool = True, indexed: bool = True) -> None:
    """gridmap's JSON layout (schemas/mcap-log.md): /sensors, /odom, /ground_truth, /range.

    ``indexed=False`` writes no summary section (no index, no statistics) and no chunks, as a
    streaming recorder may.
    """

    def ts(ns: int) -> dict[str, int]:
        return {"sec": ns // S, "nsec": ns % S}

    with open(path, "wb") as handle:
        if indexed:
            w = Writer(handle)
        else:
            w = Writer(handle, index_types=IndexType.NONE, repeat_channels=False,
                       repeat_schemas=False, use_chunking=False, use_statistics=False,
                       use_summary_offsets=False)  # fmt: skip
        w.start(profile="", library="gridmap tests")
        ids = {}
        for topic, schema in (("/sensors", "gridmap.RangeSensor"), ("/odom", "gridmap.Pose2D"),
                              ("/ground_truth", "gridmap.Pose2D"),
                              ("/range", "gridmap.RangeReading")):  # fmt: skip
            sid = w.register_schema(schema, "jsonschema", b'{"type": "object"}')
            ids[topic] = w.register_channel(topic, "json", sid)

        def put(topic: str, ns: int, msg: dict[str, object]) -> None:
            w.add_message(ids[topic], ns, json.dumps({"timestamp": ts(ns), **msg}).encode(), ns)

        for name, y, yaw in (("left", 0.1, 1.5707963267948966), ("right", -0.1, -1.0)):
            put("/sensors", S, {"name": name, "kind": "sonar", "x": 0.0, "y": y, "yaw": yaw,
                                "beam_width": 0.4363323129985824, "min_range": 0.15,
                                "max_range": 4.335})  # fmt: skip
        for k in range(3):
            ns = S + k * S // 10
            put("/odom", ns, {"frame_id": "odom", "child_frame_id": "base_link", "x": 0.1 * k,
                              "y": 0.0, "theta": 0.0})  # fmt: skip
            if truth:
                put("/ground_truth", ns, {"frame_id": "world", "child_frame_id": "base_link",
                                          "x": 5.0 + 0.1 * k, "y": 1.0, "theta": 0.0})  # fmt: skip
            put("/range", ns, {"sensor": "left", "range": 1.25 + k})
            put("/range", ns, {"sensor": "right", "range": 4.335})
        w.add_metadata("gridmap", {"robot": "p3at", "seed": "7"})
        w.finish()


def test_gridmap_json_channels(tmp_path: Path) -> None:
    path = tmp_path / "sim.mcap"
    write_json_log(path)
    log = read_log(path)
    assert log.sensor_names == ("left", "right")
    assert log.sensors is not None
    assert [(s.name, s.y_m, s.yaw_rad) for s in log.sensors] == [
        ("left", 0.1, 1.5707963267948966),
        ("right", -0.1, -1.0),
    ]
    assert log.poses.stamp_ns.tolist() == [S, S + S // 10, S + 2 * S // 10]
    assert log.poses.x_m.tolist() == [0.0, 0.1, 0.2]
    assert log.truth is not None
    assert log.truth.x_m.tolist() == [5.0, 5.1, 5.2]
    assert log.readings.sensor.tolist() == [0, 1, 0, 1, 0, 1]
    assert log.readings.range_m.tolist() == [1.25, 4.335, 2.25, 4.335, 3.25, 4.335]
    assert log.metadata == {"robot": "p3at", "seed": "7"}


def test_gridmap_json_build_uses_ground_truth_with_pose_global(tmp_path: Path) -> None:
    path = tmp_path / "sim.mcap"
    write_json_log(path)
    origins = []
    for pose in ("odometry", "global"):
        code, out, err = run("build", str(path), "-o", str(tmp_path / f"{pose}.png"), "--pose",
                             pose, "--json")  # fmt: skip
        assert code == 0, err
        origins.append(json.loads(out)["map"]["origin"])
    # the ground-truth track is the odometry moved by (5, 1) m: so is the map
    assert origins[1][0] - origins[0][0] == pytest.approx(5.0, abs=0.051)
    assert origins[1][1] - origins[0][1] == pytest.approx(1.0, abs=0.051)


def test_a_file_without_summary_or_index_is_read_from_start_to_end(tmp_path: Path) -> None:
    indexed, bare = tmp_path / "indexed.mcap", tmp_path / "bare.mcap"
    write_json_log(indexed)
    write_json_log(bare, indexed=False)
    with open(bare, "rb") as handle:
        assert SeekingReader(handle).get_summary() is None  # nothing but the data section
    survey = survey_mcap(bare)
    assert survey.indexed is False
    assert [(c.topic, c.count) for c in survey.channels] == [
        ("/sensors", 2), ("/odom", 3), ("/ground_truth", 3), ("/range", 6)
    ]  # fmt: skip
    assert (survey.message_count, survey.start_ns, survey.end_ns) == (14, S, S + S // 5)
    assert survey.metadata == {"gridmap": {"robot": "p3at", "seed": "7"}}
    want, got = read_log(indexed), read_log(bare)
    for a, b in ((want.poses, got.poses), (want.truth, got.truth)):
        assert a is not None and b is not None
        assert np.array_equal(a.stamp_ns, b.stamp_ns) and np.array_equal(a.x_m, b.x_m)
    for field_name in ("stamp_ns", "sensor", "range_m"):
        assert np.array_equal(getattr(want.readings, field_name),
                              getattr(got.readings, field_name))  # fmt: skip
    assert (got.sensors, got.metadata) == (want.sensors, want.metadata)


@given(st.integers(min_value=0, max_value=100_000))
def test_float32_fields_read_back_as_the_millimetres_written(mm: int) -> None:
    written = mm / 1000
    assert float32_decimal(np.float32(written))[0] == written


@given(st.floats(min_value=-1e6, max_value=1e6, width=32))
def test_float32_decimal_stands_for_the_same_float32(value: float) -> None:
    assert np.float32(float32_decimal(value)[0]) == np.float32(value)


def test_float32_decimal_keeps_non_finite_values() -> None:
    out = float32_decimal([math.inf, -math.inf, math.nan, 0.5])
    assert out[0] == math.inf and out[1] == -math.inf and math.isnan(out[2]) and out[3] == 0.5


def test_posestamped_odometry_and_undecodable_other_topics(tmp_path: Path) -> None:
    # only the topics gridmap uses are decoded: a protobuf camera topic (no decoder) is no problem
    path = tmp_path / "pose.mcap"
    with Recording(path) as rec:
        for k in range(3):
            ns = S + k * S
            pose = {"position": {"x": float(k), "y": 0.0, "z": 0.0}, "orientation": turn(0.5)}
            rec.write("/pose", "geometry_msgs/PoseStamped", ns,
                      {"header": rec.header(ns, "odom"), "pose": pose})  # fmt: skip
            rec.write("/sonar", "sensor_msgs/Range", ns, sonar_range(rec, ns, "base_link", 1.0))
        raw = rec.writer._writer
        schema = raw.register_schema("foxglove.CompressedImage", "protobuf", b"\x00")
        channel = raw.register_channel("/camera", "protobuf", schema)
        raw.add_message(channel, S, b"\xff\xfe", S)
    log = read_log(path)
    assert log.poses.x_m.tolist() == [0.0, 1.0, 2.0]
    assert log.poses.theta_rad.tolist() == pytest.approx([0.5, 0.5, 0.5])
    assert log.sensors is not None and log.sensors[0].x_m == 0.0  # frame = base frame


def test_a_used_topic_without_a_decoder_is_an_error_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "proto.mcap"
    with Recording(path) as rec:
        drive(rec)
        raw = rec.writer._writer
        schema = raw.register_schema("sensor_msgs/msg/Range", "protobuf", b"\x00")
        raw.add_message(raw.register_channel("/sonar", "protobuf", schema), S, b"\xff", S)
    with pytest.raises(InputFileError) as err:
        read_log(path)
    assert str(err.value) == f"{path}: /sonar: cannot decode protobuf messages of sensor_msgs/Range"
