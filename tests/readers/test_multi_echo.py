"""sensor_msgs/MultiEchoLaserScan in ROS 2 recordings (rosbag2, sqlite3 and MCAP storage): each
beam read as its first echo, a beam without an echo as no reading. The ROS 1 bag path is in
tests/test_pioneer_bag.py (a simulated run mapped byte for byte as its single-echo bag)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Bag2Writer
from rosbags.typesys import Stores, get_typestore

from gridmap_cli.readers import read_logs
from gridmap_cli.readers.options import ReadOptions

STORE = get_typestore(Stores.ROS2_HUMBLE)
T = STORE.types
START_NS = 10**18
SCANS, BEAMS = 20, 181


def _header(ns: int, frame: str) -> object:
    stamp = T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
    return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)


def _echoes(k: int, i: int) -> np.ndarray:
    """Beam ``i`` of scan ``k``: every tenth beam no echo at all, the rest a first echo at
    2 m + a centimetre a beam and a second 1.5 m behind it."""
    if i % 10 == 0:
        return np.zeros(0, dtype=np.float32)
    first = 2.0 + 0.01 * i
    return np.array([first, first + 1.5], dtype=np.float32)


def _write(target: Path, storage: StoragePlugin) -> Path:
    """A rosbag2 folder: odometry driving forward, the laser 0.1 m ahead on /tf_static, and
    multi-echo scans."""
    q = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
    zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    with Bag2Writer(target, version=8, storage_plugin=storage) as w:
        scan = w.add_connection("/scan", "sensor_msgs/msg/MultiEchoLaserScan", typestore=STORE)
        odom = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=STORE)
        tfs = w.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=STORE)
        mount = T["geometry_msgs/msg/TransformStamped"](
            header=_header(START_NS, "base_link"), child_frame_id="laser",
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=0.1, y=0.0, z=0.0), rotation=q),
        )  # fmt: skip
        tf = T["tf2_msgs/msg/TFMessage"](transforms=[mount])
        w.write(tfs, START_NS, STORE.serialize_cdr(tf, "tf2_msgs/msg/TFMessage"))
        for k in range(SCANS):
            ns = START_NS + k * 100_000_000
            pose = T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=0.05 * k, y=0.0, z=0.0), orientation=q
            )
            odometry = T["nav_msgs/msg/Odometry"](
                header=_header(ns, "odom"), child_frame_id="base_link",
                pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero),
                    covariance=np.zeros(36)),
            )  # fmt: skip
            w.write(odom, ns, STORE.serialize_cdr(odometry, "nav_msgs/msg/Odometry"))
            echoes = [T["sensor_msgs/msg/LaserEcho"](echoes=_echoes(k, i)) for i in range(BEAMS)]
            msg = T["sensor_msgs/msg/MultiEchoLaserScan"](
                header=_header(ns, "laser"), angle_min=-math.pi / 2, angle_max=math.pi / 2,
                angle_increment=math.pi / (BEAMS - 1), time_increment=0.0, scan_time=0.1,
                range_min=0.1, range_max=30.0, ranges=echoes, intensities=[],
            )  # fmt: skip
            w.write(scan, ns, STORE.serialize_cdr(msg, "sensor_msgs/msg/MultiEchoLaserScan"))
    return target


@pytest.mark.parametrize("storage", [StoragePlugin.SQLITE3, StoragePlugin.MCAP])
def test_a_rosbag2_multi_echo_laser_reads_its_first_echoes(
    tmp_path: Path, storage: StoragePlugin
) -> None:
    log = read_logs((_write(tmp_path / "run", storage),), None, ReadOptions())
    lasers = [s for s in log.sensors if s.kind == "laser"]
    assert len(lasers) == BEAMS and {(s.x_m, s.y_m) for s in lasers} == {(0.1, 0.0)}
    r = log.readings
    # every tenth beam (0, 10, ..., 180: 19 of 181) had no echo: no reading
    assert len(r.range_m) == SCANS * (BEAMS - 19)
    names = np.array(log.sensor_names)[r.sensor]
    beam = np.array([int(n.rsplit("_", 1)[1]) for n in names])
    assert not np.any(beam % 10 == 0)
    np.testing.assert_allclose(r.range_m, 2.0 + 0.01 * beam, atol=1e-6)
