"""TF in ROS recordings: moving transforms are never a mounting; chains are composed over time.

Recordings are written inline (ROS 1 style: every transform on /tf, fixed ones republished, as
robot_state_publisher does in ROS 1), with the robot driving along x while a localiser's
map -> odom correction turns and shifts it.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.errors import InputFileError, UsageError
from gridmap_cli.readers import read_log
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros.mcap.log import read_mcap
from tests.helpers import names, run
from tests.readers.mcap_helpers import DATA, Recording, S, odometry, sonar_range, turn

#: map -> odom: the localiser's correction (x, y, yaw), constant over the run
CORRECTION = (2.0, 1.0, math.pi / 2)


def tf_message(rec: Recording, *transforms: dict[str, object]) -> dict[str, object]:
    return {"transforms": list(transforms)}


def ros1_tf_recording(
    path: Path,
    sensor_parent: str = "base_link",
    laser_moves: bool = False,
    footprint: bool = False,
) -> Path:
    """ROS 1, /tf only: odom -> base (0.1 m per 0.1 s along x from t = 1 s), map -> odom
    (CORRECTION, at 2 Hz), base_link -> sonar (x 0.2, fixed; turning with time if
    ``laser_moves``), optionally odom -> base_footprint -> base_link; one sonar reading a step."""
    base = "base_footprint" if footprint else "base_link"
    with Recording(path, ros=1) as rec:
        for k in range(11):
            ns = S + k * S // 10
            moving = [rec.transform(ns, "odom", base, 0.1 * k, 0.0, 0.0)]
            if footprint:
                moving.append(rec.transform(ns, "base_footprint", "base_link", 0.0, 0.0, 0.0))
            yaw = 0.1 * k if laser_moves else 0.0
            moving.append(rec.transform(ns, sensor_parent, "sonar", 0.2, 0.0, yaw))
            if k % 5 == 0:
                moving.append(rec.transform(ns, "map", "odom", *CORRECTION))
            rec.write("/tf", "tf/tfMessage", ns, tf_message(rec, *moving))
            rec.write("/sonar", "sensor_msgs/Range", ns, sonar_range(rec, ns, "sonar", 1.0))
    return path


def test_moving_odometry_is_never_a_mounting_and_map_frame_odometry_is_composed(
    tmp_path: Path,
) -> None:
    # the bug of issue 14: --odom-frame map took odom -> base_link (its last value) as a mounting
    path = ros1_tf_recording(tmp_path / "run.mcap")
    read = read_mcap(path, ReadOptions(odom_frame="map"))
    log = read.log
    assert read.base_frame == "base_link"  # the lowest moving frame below map, not 'odom'
    assert read.static_frames == ("sonar",)  # only the fixed transform is a mounting
    assert log.sensors is not None and (log.sensors[0].x_m, log.sensors[0].y_m) == (0.2, 0.0)
    # map -> base_link = CORRECTION composed with (0.1 k, 0, 0): the robot drives along map y
    cx, cy, cyaw = CORRECTION
    k = np.arange(11)
    assert np.allclose(log.poses.x_m, cx - 0.0 * k, atol=1e-12)
    assert np.allclose(log.poses.y_m, cy + 0.1 * k, atol=1e-12)
    assert np.allclose(log.poses.theta_rad, cyaw)


def test_the_map_chain_is_the_reference_track(tmp_path: Path) -> None:
    path = ros1_tf_recording(tmp_path / "run.mcap")
    read = read_mcap(path)
    assert read.truth_from == "TF map -> odom -> base_link"
    assert np.allclose(read.log.poses.x_m, 0.1 * np.arange(11), atol=1e-12)
    truth = read.log.truth
    assert truth is not None and len(truth) == 11
    assert np.allclose(truth.y_m, CORRECTION[1] + 0.1 * np.arange(11), atol=1e-12)
    # --pose global maps with it: the map's origin moves with the correction
    out = tmp_path / "maps"
    out.mkdir()
    code, _, err = run("build", str(path), "-o", str(out / "odom.png"), "-q")
    assert code == 0, err
    code, _, err = run("build", str(path), "-o", str(out / "map.png"), "--pose", "global", "-q")
    assert code == 0, err
    assert (out / "odom.yaml").read_text() != (out / "map.yaml").read_text()


def test_a_chain_through_a_moving_footprint_is_composed(tmp_path: Path) -> None:
    path = ros1_tf_recording(tmp_path / "run.mcap", footprint=True)
    read = read_mcap(path)
    # odom -> base_footprint moves, base_footprint -> base_link is republished unchanged
    assert read.base_frame == "base_footprint"
    assert set(read.static_frames) == {"base_link", "sonar"}
    assert np.allclose(read.log.poses.x_m, 0.1 * np.arange(11), atol=1e-12)
    assert read.log.sensors is not None and read.log.sensors[0].x_m == pytest.approx(0.2)


def test_a_sensor_on_a_moving_joint_is_refused_by_name(tmp_path: Path) -> None:
    path = ros1_tf_recording(tmp_path / "run.mcap", laser_moves=True)
    with pytest.raises(InputFileError) as err:
        read_log(path)
    assert str(err.value) == (
        f"{path}: sensor frame 'sonar' (/sonar): mounting pose unknown: its transform from "
        "'base_link' changes over time (a moving joint), and gridmap maps sensors with a fixed "
        "mounting, and no --robot describing it"
    )


def test_interpolated_links_turn_along_the_shorter_arc(tmp_path: Path) -> None:
    # map -> odom turns from +170 to -170 degrees between its two samples: halfway is 180
    path = tmp_path / "run.mcap"
    with Recording(path, ros=1) as rec:
        for k in range(3):
            ns = S + k * S // 2
            moving = [rec.transform(ns, "odom", "base_link", 0.0, 0.0, 0.0)]
            if k != 1:
                yaw = math.radians(170.0 if k == 0 else -170.0)
                moving.append(rec.transform(ns, "map", "odom", 0.0, 0.0, yaw))
            moving.append(rec.transform(ns, "base_link", "sonar", 0.0, 0.0, 0.0))
            rec.write("/tf", "tf/tfMessage", ns, tf_message(rec, *moving))
            rec.write("/sonar", "sensor_msgs/Range", ns, sonar_range(rec, ns, "sonar", 1.0))
    truth = read_log(path).truth
    assert truth is not None
    assert abs(truth.theta_rad[1]) == pytest.approx(math.pi)


def amcl_recording(path: Path) -> Path:
    """ROS 2: /odom, /tf_static mounting, a sonar and /amcl_pose (PoseWithCovarianceStamped)."""
    with Recording(path) as rec:
        mount = rec.transform(0, "base_link", "sonar", 0.0, 0.0, 0.0)
        rec.write("/tf_static", "tf2_msgs/TFMessage", S, {"transforms": [mount]})
        for k in range(11):
            ns = S + k * S // 10
            rec.write("/odom", "nav_msgs/Odometry", ns, odometry(rec, ns, 0.1 * k, 0.0, 0.0))
            rec.write("/sonar", "sensor_msgs/Range", ns, sonar_range(rec, ns, "sonar", 1.0))
            if k % 2 == 0:
                pose = {"position": {"x": 5.0 + 0.1 * k, "y": 0.0, "z": 0.0},
                        "orientation": turn(0.0)}  # fmt: skip
                amcl = {"header": rec.header(ns, "map"), "pose": {"pose": pose}}
                rec.write("/amcl_pose", "geometry_msgs/PoseWithCovarianceStamped", ns, amcl)
    return path


def test_a_single_amcl_pose_topic_is_the_reference(tmp_path: Path) -> None:
    path = amcl_recording(tmp_path / "run.mcap")
    read = read_mcap(path)
    assert read.truth_from == "/amcl_pose (geometry_msgs/PoseWithCovarianceStamped)"
    assert read.log.truth is not None
    assert read.log.truth.x_m.tolist() == pytest.approx([5.0, 5.2, 5.4, 5.6, 5.8, 6.0])
    chosen = read_mcap(path, ReadOptions(pose_topic="/amcl_pose")).log.truth
    assert chosen is not None and len(chosen) == 6


@pytest.mark.parametrize(
    ("topic", "message"),
    [
        ("/nope", "--pose-topic /nope: no such topic; topics: /tf_static"),
        ("/sonar", "--pose-topic /sonar is sensor_msgs/Range, not a pose type (nav_msgs/Odometry"),
        ("/odom", "--pose-topic /odom is the odometry; the reference track must come from another"),
    ],
)
def test_a_bad_pose_topic_is_a_usage_error(tmp_path: Path, topic: str, message: str) -> None:
    path = amcl_recording(tmp_path / "run.mcap")
    with pytest.raises(UsageError) as err:
        read_log(path, options=ReadOptions(pose_topic=topic))
    assert str(err.value).startswith(f"{path}: {message}")
    out = tmp_path / "out"
    out.mkdir()
    code, _, stderr = run("build", str(path), "-o", str(out / "m.png"), "--pose-topic", topic)
    assert code == 2 and stderr.startswith("Error: ") and stderr.count("\n") == 1
    assert names(out) == set()


def test_pose_topic_is_refused_for_a_csv(tmp_path: Path) -> None:
    csv = Path(__file__).resolve().parents[2] / "samples" / "corridor_loop.csv"
    code, _, err = run("build", str(csv), "-o", str(tmp_path / "m.png"), "--pose-topic", "/x")
    assert code == 2
    assert err.strip() == (
        "Error: --pose-topic only applies to ROS recordings (MCAP, bag, rosbag2), not to CSV logs"
    )


@pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/mcap is not present")
def test_turtlebot_map_chain_agrees_with_amcl_pose() -> None:
    # AMCL publishes /amcl_pose and the map -> odom that puts odom -> base_link on it: the
    # composed chain, interpolated at the pose's stamps, agrees with the pose
    path = DATA / "rosbag2_turtlebot_odometry.mcap"
    from_tf = read_mcap(path, strict=False)
    from_topic = read_mcap(path, ReadOptions(pose_topic="/amcl_pose"), strict=False)
    assert from_tf.truth_from == "TF map -> odom -> base_link"
    assert from_topic.truth_from == "/amcl_pose (geometry_msgs/PoseWithCovarianceStamped)"
    chain, amcl = from_tf.log.truth, from_topic.log.truth
    assert chain is not None and amcl is not None and len(amcl) == 135
    inside = (amcl.stamp_ns >= chain.stamp_ns[0]) & (amcl.stamp_ns <= chain.stamp_ns[-1])
    assert inside.sum() == 134  # the first /amcl_pose comes before AMCL's first map -> odom
    t = amcl.stamp_ns[inside]
    x, y = np.interp(t, chain.stamp_ns, chain.x_m), np.interp(t, chain.stamp_ns, chain.y_m)
    gap = np.hypot(x - amcl.x_m[inside], y - amcl.y_m[inside])
    # measured: median 3.3 cm, 90 % under 7.7 cm (map -> odom is stamped ahead of the pose)
    assert float(np.median(gap)) < 0.05 and float(np.percentile(gap, 90)) < 0.1
