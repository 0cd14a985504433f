"""The MCAP reader on real recordings from ../shared/data/mcap (skipped when absent).

Facts asserted here were read from the files with the mcap library (see SOURCES.md there).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.errors import InputFileError
from gridmap_cli.readers import read_log, resolve_format
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros.mcap.channels import survey_mcap
from gridmap_cli.readers.ros.topics import plan_topics
from gridmap_cli.robot import load_robot
from tests.helpers import names, run
from tests.readers.mcap_helpers import DATA, Recording, merge_mcaps, sonar_range

TURTLEBOT = DATA / "rosbag2_turtlebot_odometry.mcap"
SONAR = DATA / "tiago_sonar_range_ros1.mcap"
ODOM = DATA / "tiago_odometry_ros1.mcap"
SCAN = DATA / "tiago_laserscan_ros1.mcap"

pytestmark = pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/mcap is not present")

TIAGO_SONAR_YAML = """\
gridmap-robot: 1
name: tiago-base-sonar
defaults: {beam_width_deg: 28.6, min_range_m: 0.02, max_range_m: 1.0}
sensors:
  - {name: base_sonar_01_link, x_m: -0.18, y_m: 0.18, yaw_deg: 135}
  - {name: base_sonar_02_link, x_m: -0.25, y_m: 0.0, yaw_deg: 180}
  - {name: base_sonar_03_link, x_m: -0.18, y_m: -0.18, yaw_deg: -135}
"""
TIAGO_LASER_YAML = """\
gridmap-robot: 1
name: tiago-laser
sensors:
  - {name: base_laser_link, kind: laser, x_m: 0.2, y_m: 0.0, yaw_deg: 0,
     first_deg: -95, last_deg: 95, samples: 572, max_range_m: 10.0}
"""


def merged(tmp_path: Path, *sources: Path) -> Path:
    out = tmp_path / "merged.mcap"
    merge_mcaps(sources, out)
    return out


def robot_file(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "robot.yaml"
    path.write_text(text)
    return path


def test_rosbag2_survey_lists_channels_types_and_counts() -> None:
    survey = survey_mcap(TURTLEBOT)
    assert survey.profile == "ros2"
    found = {c.topic: (c.type_name, c.message_encoding, c.count) for c in survey.channels}
    assert found == {
        "/odom": ("nav_msgs/Odometry", "cdr", 2639),
        "/tf": ("tf2_msgs/TFMessage", "cdr", 5422),
        "/tf_static": ("tf2_msgs/TFMessage", "cdr", 1),
        "/amcl_pose": ("geometry_msgs/PoseWithCovarianceStamped", "cdr", 135),
    }
    assert survey.message_count == 8197
    assert (survey.end_ns - survey.start_ns) / 1e9 == pytest.approx(97.355, abs=0.001)
    assert resolve_format(TURTLEBOT).name == "mcap"


def test_rosbag2_without_range_topics_is_an_error_listing_the_topics() -> None:
    with pytest.raises(InputFileError) as err:
        read_log(TURTLEBOT)
    assert "no range readings" in str(err.value)
    assert "/odom (nav_msgs/Odometry, 2639 messages)" in str(err.value)
    assert "/amcl_pose (geometry_msgs/PoseWithCovarianceStamped, 135 messages)" in str(err.value)


def test_rosbag2_odometry_and_tf_chain_with_a_range_topic_added(tmp_path: Path) -> None:
    # a sonar on the TurtleBot's rplidar_link: base_link -> shell_link (z 0.0942) -> rplidar_link
    # (x -0.04, z 0.0987, yaw +90 deg) in the recording's /tf_static; header stamps are sim time
    extra = tmp_path / "extra.mcap"
    with Recording(extra) as rec:
        for k in range(3):
            ns = 930_000_000_000 + k * 100_000_000
            rec.write("/sonar", "sensor_msgs/Range", ns, sonar_range(rec, ns, "rplidar_link", 1.5))
    log = read_log(merged(tmp_path, TURTLEBOT, extra))
    assert len(log.poses) == 2639
    assert log.poses.stamp_ns[0] == 928_800_000_000  # header stamp, not the log time
    assert np.all(np.diff(log.poses.stamp_ns) > 0)
    assert log.poses.x_m[0] == pytest.approx(-2.8019166340612314)
    # quaternion (0, 0, 0.0846, -0.9964), the same rotation as (0, 0, -0.0846, 0.9964): a turn
    # of -9.703 degrees (-0.16935 rad) about z
    assert log.poses.theta_rad[0] == pytest.approx(-0.1693494871, abs=1e-10)
    assert log.sensor_names == ("rplidar_link",)
    assert log.sensors is not None
    s = log.sensors[0]
    assert (s.x_m, s.y_m) == pytest.approx((-0.04, 0.0), abs=1e-12)
    assert s.yaw_rad == pytest.approx(math.pi / 2)
    assert len(log.readings) == 3


def test_rosbag2_tf_odometry_matches_the_odometry_topic(tmp_path: Path) -> None:
    extra = tmp_path / "extra.mcap"
    with Recording(extra) as rec:
        rec.write("/sonar", "sensor_msgs/Range", 1, sonar_range(rec, 930 * 10**9, "base_link", 1))
    both = merged(tmp_path, TURTLEBOT, extra)
    from_topic = read_log(both)
    from_tf = read_log(both, options=ReadOptions(odom_topic="/tf"))
    assert len(from_tf.poses) == 2639
    assert np.array_equal(from_tf.poses.stamp_ns, from_topic.poses.stamp_ns)
    assert np.allclose(from_tf.poses.x_m, from_topic.poses.x_m)
    assert np.allclose(from_tf.poses.theta_rad, from_topic.poses.theta_rad)


def test_tiago_sonar_reads_three_sonars_with_no_echo_at_max_range(tmp_path: Path) -> None:
    robot = load_robot(str(robot_file(tmp_path, TIAGO_SONAR_YAML)))
    log = read_log(merged(tmp_path, SONAR, ODOM), options=ReadOptions(robot=robot))
    assert log.sensor_names == ("base_sonar_01_link", "base_sonar_02_link", "base_sonar_03_link")
    assert log.sensors is not None
    for s in log.sensors:
        assert s.beam_width_rad == 0.5
        assert s.min_range_m == 0.02  # float32 0.0199999995, read as the decimal it stands for
        assert s.max_range_m == 1.0
    assert len(log.readings) == 609
    assert np.bincount(log.readings.sensor).tolist() == [203, 203, 203]
    assert int(np.count_nonzero(log.readings.range_m == 1.0)) == 442  # no echo
    assert log.readings.range_m.min() == 0.46
    span = log.readings.stamp_ns[-1] - log.readings.stamp_ns[0]
    assert span == 1744122953734016135 - 1744122933178386583
    # odometry: 1301 messages, child frame base_footprint (the base frame found from them)
    assert len(log.poses) == 1301
    assert log.poses.stamp_ns[0] == 1744123206965573590


def test_tiago_sonar_without_mounting_names_the_missing_frame(tmp_path: Path) -> None:
    log = merged(tmp_path, SONAR, ODOM)
    with pytest.raises(InputFileError) as err:
        read_log(log)
    assert str(err.value) == (
        f"{log}: sensor frame 'base_sonar_01_link' (/sonar_base): mounting pose unknown: the "
        "recording has no TF, and no --robot describing it"
    )


def test_tiago_sonar_and_odometry_from_different_times_is_a_clear_build_error(
    tmp_path: Path,
) -> None:
    log = merged(tmp_path, SONAR, ODOM)
    robot = robot_file(tmp_path, TIAGO_SONAR_YAML)
    code, _, err = run("build", str(log), "-o", str(tmp_path / "map.png"), "--robot", str(robot))
    assert code == 1
    assert err.strip() == (
        f"Error: {log}: no odometry during the range readings: the 609 readings span "
        "2025-04-08 14:35:33.178 UTC to 14:35:53.734 UTC (20.6 s), the odometry "
        "2025-04-08 14:40:06.965 UTC to 14:40:32.965 UTC (26.0 s) (recorded at different times?)"
    )
    assert names(tmp_path) == {"merged.mcap", "robot.yaml"}


def test_tiago_laserscan_beams(tmp_path: Path) -> None:
    robot = load_robot(str(robot_file(tmp_path, TIAGO_LASER_YAML)))
    log = read_log(merged(tmp_path, SCAN, ODOM), options=ReadOptions(robot=robot))
    assert len(log.sensor_names) == 572
    assert log.sensor_names[0] == "base_laser_link_0"
    assert log.sensor_names[-1] == "base_laser_link_571"
    assert log.sensors is not None
    assert {s.kind for s in log.sensors} == {"laser"}
    assert {s.max_range_m for s in log.sensors} == {10.0}
    assert {s.min_range_m for s in log.sensors} == {0.05}
    # 274 scans of 572 beams; NaN (710 of them) is no reading, -inf (348) "too close" (REP 117)
    # is dropped, +inf (3055) is no echo: stored at the maximum range
    assert len(log.readings) == 274 * 572 - 710 - 348
    assert int(np.count_nonzero(log.readings.range_m == 10.0)) == 3055
    assert log.readings.range_m.min() >= 0.05
    assert len(np.unique(log.readings.stamp_ns)) == 274


def test_tiago_odometry_alone_has_no_range_topic() -> None:
    survey = survey_mcap(ODOM)
    assert [(c.topic, c.type_name, c.count) for c in survey.channels] == [
        ("/mobile_base_controller/odom", "nav_msgs/Odometry", 1301)
    ]
    with pytest.raises(InputFileError, match="no range readings"):
        plan_topics(survey, ReadOptions())


def test_calibrate_needs_no_range_readings(tmp_path: Path) -> None:
    """The TurtleBot recording holds odometry and a localiser's track, no ranges: enough to
    calibrate the odometry against the track (which build refuses: nothing to map)."""
    import json

    out = tmp_path / "odometry.yaml"
    code, stdout, err = run("calibrate", str(TURTLEBOT), "-o", str(out), "--json")
    assert code == 0, err
    doc = json.loads(stdout)
    assert doc["windows"]["total"] >= 20 and doc["estimated"]["distance"]
    assert out.is_file()
    code, _, err = run("build", str(TURTLEBOT), "-o", str(tmp_path / "map.png"))
    assert code == 1 and "no range readings" in err
