"""The bag readers on real recordings from ../shared/data (skipped when absent).

The TIAGo bags are the originals of the TIAGo MCAP files (same messages and receive times, see
SOURCES.md there): read through ``rosbags`` they must give what the MCAP reader gives.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.readers import read_logs, resolve_format
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros.bag.log import read_bag
from gridmap_cli.robot import load_robot
from tests.helpers import names, run
from tests.readers.test_mcap_real import TIAGO_LASER_YAML, TIAGO_SONAR_YAML, robot_file

SHARED = Path(__file__).resolve().parents[3] / "shared" / "data"
BAGS = SHARED / "bag"
MCAPS = SHARED / "mcap"
ROSBAG2 = SHARED / "rosbag2" / "tf_example"

pytestmark = pytest.mark.skipif(not BAGS.is_dir(), reason="../shared/data/bag is not present")


@pytest.mark.parametrize(
    ("bag", "mcap", "robot_yaml"),
    [
        ("tiago_sonar.bag", "tiago_sonar_range_ros1.mcap", TIAGO_SONAR_YAML),
        ("tiago_scan_lidar.bag", "tiago_laserscan_ros1.mcap", TIAGO_LASER_YAML),
    ],
)
def test_tiago_bags_read_like_their_mcap_copies(
    tmp_path: Path, bag: str, mcap: str, robot_yaml: str
) -> None:
    options = ReadOptions(robot=load_robot(str(robot_file(tmp_path, robot_yaml))))
    from_bag = read_logs([BAGS / "tiago_odometry.bag", BAGS / bag], options=options)
    from_mcap = read_logs([MCAPS / "tiago_odometry_ros1.mcap", MCAPS / mcap], options=options)
    assert resolve_format(BAGS / bag).name == "bag"
    assert from_bag.sensor_names == from_mcap.sensor_names
    assert from_bag.sensors == from_mcap.sensors
    assert len(from_bag.poses) == 1301
    for field in ("stamp_ns", "x_m", "y_m", "theta_rad"):
        assert np.array_equal(getattr(from_bag.poses, field), getattr(from_mcap.poses, field))
    for field in ("stamp_ns", "sensor", "range_m"):
        assert np.array_equal(getattr(from_bag.readings, field), getattr(from_mcap.readings, field))
    assert len(from_bag.readings) == {"tiago_sonar.bag": 609}.get(bag, 274 * 572 - 710 - 348)


def test_the_split_tiago_bags_give_the_clear_error_with_both_time_spans(tmp_path: Path) -> None:
    robot = robot_file(tmp_path, TIAGO_SONAR_YAML)
    odometry, sonar = BAGS / "tiago_odometry.bag", BAGS / "tiago_sonar.bag"
    out = tmp_path / "map.png"
    code, _, err = run("build", str(odometry), str(sonar), "-o", str(out), "--robot", str(robot))
    assert code == 1
    assert err.strip() == (
        f"Error: {odometry} + {sonar}: no odometry during the range readings: the 609 readings "
        "span 2025-04-08 14:35:33.178 UTC to 14:35:53.734 UTC (20.6 s), the odometry "
        "2025-04-08 14:40:06.965 UTC to 14:40:32.965 UTC (26.0 s) (recorded at different times?)"
    )
    assert names(tmp_path) == {"robot.yaml"}


def test_inspect_of_a_tiago_bag_lists_what_its_mcap_lists() -> None:
    code, out, err = run("inspect", str(BAGS / "tiago_sonar.bag"))
    assert code == 1 and err.startswith(f"Error: {BAGS / 'tiago_sonar.bag'}: no odometry")
    assert "/sonar_base  sensor_msgs/Range  ros1      609" in out
    assert "609 messages, log time 2025-04-08 14:35:33.381 UTC to 14:35:53.932 UTC (20.6 s)" in out
    _, from_mcap, _ = run("inspect", str(MCAPS / "tiago_sonar_range_ros1.mcap"))
    rows = [line for line in out.splitlines() if line.startswith("  /sonar_base ")]
    assert rows == [line for line in from_mcap.splitlines() if line.startswith("  /sonar_base ")]


def test_the_evo_bag_and_its_rosbag2_copy_give_the_same_tf_odometry() -> None:
    bag = read_bag(BAGS / "evo_tf_example.bag", strict=False)
    folder = read_bag(ROSBAG2, strict=False)
    assert resolve_format(ROSBAG2).name == "rosbag2"
    assert bag.survey.profile == "ros1" and folder.survey.profile == "ros2"
    for read in (bag, folder):
        assert read.tf_pairs == {("odom", "base_footprint"): 517}
        assert read.base_frame == "base_footprint"
        assert read.static_frames == ("base_link",)  # /tf_static: base_footprint -> base_link
        assert len(read.log.poses) == 517
        assert "no range readings" in str(read.problem)
    assert np.array_equal(bag.log.poses.stamp_ns, folder.log.poses.stamp_ns)
    assert np.array_equal(bag.log.poses.x_m, folder.log.poses.x_m)
    assert np.array_equal(bag.log.poses.theta_rad, folder.log.poses.theta_rad)
    # the first odom -> base_footprint transform, as printed by rosbags
    assert bag.log.poses.x_m[0] == pytest.approx(1.1603796887148006)
    assert bag.log.poses.y_m[0] == pytest.approx(-2.942426888388735)


def test_inspect_reads_like_ros2_bag_info_storage_compression_files_and_qos() -> None:
    code, out, _ = run("inspect", str(ROSBAG2))
    assert code == 1  # no range readings: build would fail, and inspect says so
    assert (
        "  storage sqlite3, compression none; 2 files: metadata.yaml (1,052 bytes), "
        "tf_example.db3 (0.1 MB)"
    ) in out.splitlines()
    code, out, _ = run("inspect", str(MCAPS / "rosbag2_turtlebot_odometry.mcap"), "--json")
    doc = json.loads(out)
    assert (doc["mcap"]["storage"], doc["mcap"]["compression"]) == ("mcap", "zstd")
    qos = {c["topic"]: c["qos"] for c in doc["mcap"]["channels"]}
    assert qos["/tf_static"] == "reliable, transient_local, depth 1"
    assert qos["/tf"] == "reliable, volatile, depth 10 (+2 publishers)"


def test_inspect_describes_split_bags_as_the_recording_build_reads() -> None:
    odometry, sonar = BAGS / "tiago_odometry.bag", BAGS / "tiago_sonar.bag"
    code, out, err = run("inspect", str(odometry), str(sonar), "--json")
    assert code == 1 and "sensor frame 'base_sonar_01_link' (/sonar_base): mounting pose" in err
    doc = json.loads(out)
    assert doc["file"] == f"{odometry} + {sonar}"
    assert [c["topic"] for c in doc["mcap"]["channels"]] == [
        "/mobile_base_controller/odom",
        "/sonar_base",
    ]
    assert doc["mcap"]["compression"] == "none"
    assert len(doc["mcap"]["files"]) == 2


def test_inspect_of_two_tiago_bags_lists_every_problem_build_would_meet(tmp_path: Path) -> None:
    """Odometry and scans recorded minutes apart, and no TF for the laser: the verdict names
    both, the mounting first (build's own error) and the time spans after it; with the mounting
    given, the time spans alone remain."""
    odometry, scans = BAGS / "tiago_odometry.bag", BAGS / "tiago_scan_lidar.bag"
    code, stdout, stderr = run("inspect", str(odometry), str(scans), "--json")
    assert code == 1
    problems = json.loads(stdout)["build"]["problems"]
    assert len(problems) == 2
    assert "mounting pose unknown" in problems[0] and "--laser-mount X,Y,YAW_DEG" in problems[0]
    assert "no odometry during the range readings" in problems[1]
    assert "14:34:28.832 UTC to 14:34:47.032 UTC" in problems[1]  # the scans' span
    assert "14:40:06.965 UTC to 14:40:32.965 UTC" in problems[1]  # the odometry's
    assert stderr.strip() == f"Error: {problems[0]}"  # the line build would stop at
    code, stdout, _ = run("inspect", str(odometry), str(scans), "--laser-mount", "0.2,0,0")
    assert code == 1
    verdict = stdout.splitlines()[-1]
    assert verdict.startswith("  -> build would fail: no odometry during the range readings")
    assert "mounting" not in stdout.split("What build would use:")[1]
