"""gridmap inspect: what a log holds and what build would use, for every format."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from gridmap_cli.robot import preset_names
from tests.helpers import run
from tests.readers.mcap_helpers import (
    DATA,
    Recording,
    S,
    drive,
    merge_mcaps,
    sonar_range,
    static_tf,
)
from tests.readers.test_mcap_log import ros2_sonar_log, ros2_sonar_messages, write_json_log

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
real = pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/mcap is not present")


def inspect_json(*args: str) -> Any:
    code, out, err = run("inspect", *args, "--json")
    assert code == 0, err
    return json.loads(out)


@real
def test_rosbag2_text_explains_channels_odometry_and_why_build_fails() -> None:
    code, out, err = run("inspect", str(DATA / "rosbag2_turtlebot_odometry.mcap"))
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0].endswith("MCAP log, 0.5 MB; profile 'ros2', written by mcap go v1.8.0; "
                             "libmcap 1.4.0")  # fmt: skip
    assert (
        "  8,197 messages, log time 2026-05-08 09:59:13.382 UTC to 10:00:50.738 UTC (97.4 s)"
        in lines
    )
    odom_row = next(line for line in lines if line.startswith("  /odom "))
    assert odom_row.split() == [
        "/odom",
        "nav_msgs/Odometry",
        "cdr",
        "2,639",
        "27.1",
        "Hz",
        "odometry",
    ]
    assert any(
        line.startswith("  /tf_static ") and line.endswith("sensor mounting") for line in lines
    )
    assert "Odometry: 2,639 poses, 928.800 s to 1025.496 s (96.7 s), 27.3 Hz" in lines
    assert any("travelled 34.32 m" in line for line in lines)
    assert "Range readings: none" in lines
    assert lines[-1] == (
        "  -> build would fail: no range readings: no sensor_msgs/Range, LaserScan, PointCloud "
        "(sonar) or gridmap.RangeReading topic"
    )


@real
def test_rosbag2_json() -> None:
    d = inspect_json(str(DATA / "rosbag2_turtlebot_odometry.mcap"))
    mcap = d["mcap"]
    assert (mcap["profile"], mcap["indexed"], mcap["messages"]) == ("ros2", True, 8197)
    assert mcap["tf"] == []  # /tf is left unread: odometry is /odom, mounting /tf_static
    counts = {c["topic"]: (c["messages"], c["used_as"]) for c in mcap["channels"]}
    assert counts == {
        "/odom": (2639, "odometry"),
        "/tf": (5422, ""),
        "/tf_static": (1, "sensor mounting"),
        "/amcl_pose": (135, ""),
    }
    assert len(mcap["static_frames"]) == 29
    assert "rplidar_link" in mcap["static_frames"]
    log = d["log"]
    assert (log["odometry"]["distance_m"], log["odometry"]["rotation_deg"]) == (34.322, 806.9)
    assert log["odometry"]["count"] == 2639
    assert log["readings"] is None
    build = d["build"]
    assert (build["ranges"], build["sensors"], build["robot"]) == ([], 0, None)
    assert build["odometry"] == "/odom (nav_msgs/Odometry)"
    assert build["frames"] == {"odom": "odom", "base": "base_link"}
    assert build["ready"] is False


@real
def test_tiago_recordings_at_different_times(tmp_path: Path) -> None:
    both = tmp_path / "tiago.mcap"
    merge_mcaps([DATA / "tiago_sonar_range_ros1.mcap", DATA / "tiago_odometry_ros1.mcap"], both)
    d = inspect_json(str(both))
    build = d["build"]
    assert (build["ranges"], build["sensors"], build["ready"]) == (["/sonar_base"], 3, False)
    assert build["frames"] == {"odom": "odom", "base": "base_footprint"}
    assert build["problem"].endswith(
        "sensor frame 'base_sonar_01_link' (/sonar_base): mounting pose unknown: the recording "
        "has no TF, and no --robot describing it"
    )
    log = d["log"]
    assert (log["odometry"]["count"], log["readings"]["count"]) == (1301, 609)
    assert [
        (s["name"], s["readings"], s["no_echo"], s["mounting_from"]) for s in log["sensors"]
    ] == [
        ("base_sonar_01_link", 203, 144, "unknown"),
        ("base_sonar_02_link", 203, 156, "unknown"),
        ("base_sonar_03_link", 203, 142, "unknown"),
    ]
    assert log["readings"]["during_odometry"] == 0
    robot = tmp_path / "tiago.yaml"
    robot.write_text(
        "gridmap-robot: 1\nname: tiago\ndefaults: {beam_width_deg: 28.6, max_range_m: 1.0}\n"
        "sensors:\n"
        + "".join(
            f"  - {{name: base_sonar_0{i}_link, x_m: 0, y_m: 0, yaw_deg: 0}}\n" for i in (1, 2, 3)
        )
    )
    with_robot = inspect_json(str(both), "--robot", str(robot))
    assert with_robot["build"]["problem"] == (
        "no odometry during the range readings (recorded at different times?)"
    )
    assert {s["mounting_from"] for s in with_robot["log"]["sensors"]} == {"robot"}


def test_csv_sample() -> None:
    d = inspect_json(str(SAMPLES / "corridor_loop.csv"))
    log = d["log"]
    assert log["metadata"]["robot"] == "p3at"
    assert log["odometry"]["count"] == 1468
    assert log["odometry"]["duration_s"] == 146.7
    assert log["odometry"]["rate_hz"] == 10.0
    assert log["truth"]["count"] == 1468
    assert log["readings"]["count"] == 23488
    assert log["readings"]["rate_hz"] == 160.102  # 23,487 intervals in 146.7 s, as for odometry
    assert [s["no_echo"] for s in log["sensors"][:3]] == [201, 183, 1109]
    assert log["readings"]["during_odometry"] == 23488
    assert len(log["sensors"]) == 16
    assert log["sensors"][0]["mounting"] == {"x_m": 0.147, "y_m": 0.136, "yaw_deg": 90.0}
    assert {s["mounting_from"] for s in log["sensors"]} == {"robot"}
    build = d["build"]
    assert build["ranges"] == ["16 sensor columns: sonar0 .. sonar15"]
    assert build["robot"] == {"name": "p3at", "from": "the log's robot line", "needed": True}
    assert build["truth"] == "columns true_x, true_y, true_theta"
    assert build["ready"] is True


def test_aria_sample_has_the_same_run_with_sonar_units_in_the_log() -> None:
    csv = inspect_json(str(SAMPLES / "corridor_loop.csv"))["log"]
    aria = inspect_json(str(SAMPLES / "corridor_loop.2d"))["log"]
    assert aria["odometry"]["distance_m"] == csv["odometry"]["distance_m"] == 56.433
    assert aria["odometry"]["rotation_deg"] == csv["odometry"]["rotation_deg"] == 284.5
    assert aria["readings"]["count"] == csv["readings"]["count"]
    assert {s["mounting_from"] for s in aria["sensors"]} == {"log"}


def test_ros2_and_json_mcaps_are_ready(tmp_path: Path) -> None:
    d = inspect_json(str(ros2_sonar_log(tmp_path / "r.mcap")))
    sensors = d["log"]["sensors"]
    assert [(s["name"], s["mounting_from"], s["mounting"]["yaw_deg"]) for s in sensors] == [
        ("sonar_left", "TF", 90.0)
    ]
    assert d["build"]["ready"] is True
    path = tmp_path / "sim.mcap"
    write_json_log(path)
    code, out, _ = run("inspect", str(path))
    assert code == 0
    assert "  truth     /ground_truth (with --pose global)" in out.splitlines()
    assert "Log header: robot: p3at, seed: 7" in out.splitlines()
    assert out.splitlines()[-1] == "  -> ready to build"


def text_lines(path: Path) -> list[str]:
    code, out, err = run("inspect", str(path))
    assert code == 0, err
    return out.splitlines()


def test_ros2_sample_text_says_what_build_does_and_skips() -> None:
    lines = text_lines(SAMPLES / "corridor_loop_ros2.mcap")
    assert lines[0].endswith("MCAP log, 0.7 MB; profile 'ros2', written by gridmap-cli")
    # /tf repeats /odom's poses: it is left unread, and the row says why
    tf_row = next(line for line in lines if line.startswith("  /tf "))
    assert tf_row.endswith("10 Hz   - (odometry is /odom)")
    # 28 readings are below the sonars' 0.15 m: build maps the rest (its summary says 23,460)
    assert (
        "  23,488 of them during the odometry's time span, 28 of these below their sensor's "
        "minimum range: build maps 23,460"
    ) in lines
    assert any(line.startswith("Range readings: 23,488 (8,539 at maximum range: no echo), ")
               for line in lines)  # fmt: skip
    # the P3-AT sonar reaches 4.335 m (ARIA's 4335 mm), not 4.33
    assert next(line for line in lines if line.startswith("  sonar0 ")).split()[6] == "0.15-4.335"
    assert "  frames    odometry 'odom', base 'base_link'" in lines
    assert (
        "  robot     p3at (the log's robot line); not needed: the log describes all 16 sensors"
        in lines
    )


def test_json_sample_text_has_no_tf_frames_and_no_profile() -> None:
    lines = text_lines(SAMPLES / "corridor_loop.mcap")
    assert lines[0].endswith("MCAP log, 0.7 MB; no profile, written by gridmap-cli")
    assert not any(line.startswith("  frames ") for line in lines)  # no TF in gridmap's channels
    assert lines[-2].endswith("not needed: the log describes all 16 sensors")


@pytest.mark.parametrize(
    ("sample", "needed"),
    [
        ("corridor_loop.csv", True),
        ("corridor_loop.2d", False),
        ("corridor_loop.mcap", False),
        ("corridor_loop_ros2.mcap", False),
    ],
)
def test_every_sample_counts_what_sync_will_skip(sample: str, needed: bool) -> None:
    d = inspect_json(str(SAMPLES / sample))
    assert d["log"]["readings"]["below_min_range"] == 28
    assert d["build"]["robot"]["needed"] is needed


def test_broken_inputs_are_errors(tmp_path: Path) -> None:
    code, _, err = run("inspect", str(tmp_path / "absent.mcap"))
    assert (code, err.strip()) == (1, f"Error: {tmp_path / 'absent.mcap'}: no such file")
    whole = ros2_sonar_log(tmp_path / "r.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(whole[:100])
    code, _, err = run("inspect", str(cut))
    assert code == 1
    assert err.startswith(f"Error: {cut}: truncated or damaged MCAP file")
    code, _, err = run("inspect", str(SAMPLES / "hall.csv"), "--odom-topic", "/odom")
    assert code == 2


def test_unknown_robot_line_is_the_error_build_stops_at(room_csv: Path, tmp_path: Path) -> None:
    room_csv.write_text(room_csv.read_text().replace("# robot: p3dx", "# robot: r2d2"))
    message = (
        f"'# robot: r2d2' is neither a preset ({', '.join(preset_names())}) nor a file beside "
        "the log; give --robot"
    )
    code, _, err = run("build", str(room_csv), "-o", str(tmp_path / "m.png"))
    assert (code, err.strip()) == (1, f"Error: {room_csv}: {message}")
    d = inspect_json(str(room_csv))
    assert (d["build"]["ready"], d["build"]["problem"]) == (False, f"{room_csv}: {message}")
    assert d["build"]["robot"] is None
    assert text_lines(room_csv)[-1] == f"  -> build would fail: {message}"


def test_channels_unused_by_build_have_their_time_span(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    with Recording(path) as rec:  # a camera, which gridmap cannot decode, beside the sonar log
        raw = rec.writer._writer
        schema = raw.register_schema("foxglove.CompressedImage", "protobuf", b"\x00")
        camera = raw.register_channel("/camera", "protobuf", schema)
        for k in range(5):
            raw.add_message(camera, S + k * S // 4, b"\xff", S)
        ros2_sonar_messages(rec)
    channels = {c["topic"]: c for c in inspect_json(str(path))["mcap"]["channels"]}
    camera_row = channels["/camera"]
    assert (camera_row["first_ns"], camera_row["last_ns"]) == (S, 2 * S)
    assert (camera_row["rate_hz"], camera_row["used_as"]) == (4.0, "")
    assert (channels["/sonar"]["first_ns"], channels["/sonar"]["last_ns"]) == (
        S + S // 10,
        S + 7 * S // 10,
    )


def test_unindexed_file_says_so_and_still_has_channel_spans(tmp_path: Path) -> None:
    path = tmp_path / "bare.mcap"
    write_json_log(path, indexed=False)
    assert "  no index: the file is read from start to end" in text_lines(path)
    d = inspect_json(str(path))
    odom = next(c for c in d["mcap"]["channels"] if c["topic"] == "/odom")
    assert (odom["messages"], odom["first_ns"], odom["last_ns"]) == (3, S, S + S // 5)
    assert (d["mcap"]["indexed"], d["build"]["ready"]) == (False, True)


def test_laser_beams_fold_into_one_row_and_a_long_table_is_cut(tmp_path: Path) -> None:
    path = tmp_path / "many.mcap"
    frames = [f"s{i:02d}" for i in range(22)]
    with Recording(path) as rec:
        static_tf(rec, *(rec.transform(0, "base_link", f, 0.1 * i, 0.0, 0.0)
                         for i, f in enumerate(frames)),
                  rec.transform(0, "base_link", "laser", 0.2, 0.0, 0.0))  # fmt: skip
        drive(rec)
        for f in frames:
            rec.write("/sonar", "sensor_msgs/Range", S, sonar_range(rec, S, f, 1.0))
        scan = {
            "header": rec.header(S, "laser"),
            "angle_min": -0.5,
            "angle_increment": 0.25,
            "range_min": 0.1,
            "range_max": 8.0,
            "ranges": [1.0, 8.0, 2.0, math.inf, 3.0],
        }
        rec.write("/scan", "sensor_msgs/LaserScan", S, scan)
    lines = text_lines(path)
    start = lines.index("Sensors: 27")  # 22 sonars and 5 beams, in 23 rows: 8, a gap, 4
    rows = [line.split() for line in lines[start + 1 : start + 15]]
    assert rows[0][:3] == ["name", "kind", "x"]
    assert [row[0] for row in rows[1:9]] == frames[:8]
    assert rows[1] == ["s00", "sonar", "0.000", "0.000", "0.0", "28.6", "0.1-3", "1", "0", "TF"]
    assert rows[9] == ["...", "11", "more", "..."]
    assert [row[0] for row in rows[10:13]] == frames[-3:]
    assert rows[13] == ["laser_0..4", "(5", "beams)", "laser", "0.200", "0.000", "-28.6..28.6",
                        "0.0", "0.1-8", "5", "2", "TF"]  # fmt: skip
    assert lines[start + 15] == ""
