"""gridmap inspect: what a log holds and what build would use, for every format."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from gridmap_cli.robot import preset_names
from tests.helpers import names, run
from tests.readers.mcap_helpers import (
    DATA,
    Recording,
    S,
    drive,
    merge_mcaps,
    sonar_range,
    static_tf,
)
from tests.readers.test_carmen_real import DATA as CARMEN
from tests.readers.test_mcap_log import ros2_sonar_log, ros2_sonar_messages, write_json_log

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
real = pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/mcap is not present")


def inspect_json(*args: str, code: int = 0) -> Any:
    """``gridmap inspect ARGS --json``, parsed; ``code`` is the exit expected (1: build would
    fail, the description printed all the same)."""
    got, out, err = run("inspect", *args, "--json")
    assert got == code, err
    return json.loads(out)


@real
def test_rosbag2_text_explains_channels_odometry_and_why_build_fails() -> None:
    code, out, err = run("inspect", str(DATA / "rosbag2_turtlebot_odometry.mcap"))
    assert code == 1, err
    assert err.startswith("Error: ") and err.count("\n") == 1
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
        "reliable,",  # the QoS rosbag2 recorded, as ros2 bag info shows it
        "volatile,",
        "depth",
        "10",
    ]
    assert any(
        line.startswith("  /tf_static ")
        and line.endswith(
            "sensor mounting                       reliable, transient_local, depth 1"
        )
        for line in lines
    )
    assert "Odometry: 2,639 poses, 928.800 s to 1025.496 s (96.7 s), 27.3 Hz" in lines
    assert any("travelled 34.32 m" in line for line in lines)
    assert "Range readings: none" in lines
    assert lines[-1] == (
        "  -> build would fail: no range readings: no sensor_msgs/Range, LaserScan, "
        "MultiEchoLaserScan, PointCloud (sonar) or gridmap.RangeReading topic"
    )


@real
def test_rosbag2_json() -> None:
    d = inspect_json(str(DATA / "rosbag2_turtlebot_odometry.mcap"), code=1)
    mcap = d["mcap"]
    assert (mcap["profile"], mcap["indexed"], mcap["messages"]) == ("ros2", True, 8197)
    # /tf is read for the reference: map -> odom (AMCL) on top of odom -> base_link; the wheels
    # turn, so their transforms are no mounting
    assert mcap["tf"] == [
        {"parent": "base_link", "child": "left_wheel", "transforms": 1862},
        {"parent": "base_link", "child": "right_wheel", "transforms": 1862},
        {"parent": "map", "child": "odom", "transforms": 921},
        {"parent": "odom", "child": "base_link", "transforms": 2639},
    ]
    counts = {c["topic"]: (c["messages"], c["used_as"]) for c in mcap["channels"]}
    assert counts == {
        "/odom": (2639, "odometry"),
        "/tf": (5422, "reference (map -> odom -> base_link)"),
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
    assert build["truth"] == "TF map -> odom -> base_link"
    assert log["truth"]["count"] == 2611  # odometry stamps within the span of map -> odom
    assert build["ready"] is False


@real
def test_tiago_recordings_at_different_times(tmp_path: Path) -> None:
    both = tmp_path / "tiago.mcap"
    merge_mcaps([DATA / "tiago_sonar_range_ros1.mcap", DATA / "tiago_odometry_ros1.mcap"], both)
    d = inspect_json(str(both), code=1)
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
    with_robot = inspect_json(str(both), "--robot", str(robot), code=1)
    problem = with_robot["build"]["problem"]  # build's own words, with the two time spans
    assert problem.startswith(f"{both}: no odometry during the range readings: the 609 readings ")
    assert problem.endswith(" (recorded at different times?)")
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
    assert "  truth     /ground_truth (gridmap.Pose2D) (with --pose global)" in out.splitlines()
    assert "Log header: robot: p3at, seed: 7" in out.splitlines()
    assert out.splitlines()[-1] == "  -> ready to build"


def text_lines(path: Path, code: int = 0) -> list[str]:
    got, out, err = run("inspect", str(path))
    assert got == code, err
    return out.splitlines()


def test_ros2_sample_text_says_what_build_does_and_skips() -> None:
    lines = text_lines(SAMPLES / "corridor_loop_ros2.mcap")
    assert lines[0].endswith("MCAP log, 0.7 MB; profile 'ros2', written by gridmap-cli")
    # /tf repeats /odom's poses: it is left unread, and the row says why
    tf_row = next(line for line in lines if line.startswith("  /tf "))
    assert tf_row.endswith("10 Hz   - (odometry is /odom)  reliable, volatile, depth 10")
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
    assert err.startswith(f"Error: {cut}: byte 100: truncated or damaged MCAP file")
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
    d = inspect_json(str(room_csv), code=1)
    assert (d["build"]["ready"], d["build"]["problem"]) == (False, f"{room_csv}: {message}")
    assert d["build"]["robot"] is None
    assert text_lines(room_csv, code=1)[-1] == f"  -> build would fail: {message}"


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
            "angle_max": 0.5,
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


# ----------------------------------------------------------- inspect's verdict is build's own

HEAD = "# robot: p3at\ntime,x,y,theta"


def csv_log(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "run.csv"
    path.write_text(text)
    return path


def aria_log(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "run.2d"
    path.write_text(text)
    return path


def mcap_log(tmp_path: Path, readings_from_s: float, odometry: bool = True) -> Path:
    """A sonar mounted by /tf_static, odometry from 1 to 2 s, and three readings from
    ``readings_from_s`` (recorded at another time when that is past 2 s)."""
    path = tmp_path / "run.mcap"
    with Recording(path) as rec:
        static_tf(rec, rec.transform(0, "base_link", "sonar", 0.1, 0.0, 0.0))
        if odometry:
            drive(rec)
        for k in range(3):
            ns = int(readings_from_s * S) + k * S // 10
            rec.write("/sonar", "sensor_msgs/Range", ns, sonar_range(rec, ns, "sonar", 1.0))
    return path


SONAR_NO_UNITS = (
    "LaserOdometryLog\nversion: 4\nlogTime: 0.1\nrobot: 0 0 0\nsonar: 500 5000\n"
    "logTime: 0.2\nrobot: 40 0 0\nsonar: 460 1200\n"
)

# (name, the log, what build's error says after the file name)
BUILD_FAILS = [
    (
        "no range columns",
        lambda t: csv_log(t, f"{HEAD}\n0,0,0,0\n0.1,0.1,0,0\n"),
        "the log holds no range readings",
    ),
    (
        "every reading empty",
        lambda t: csv_log(t, f"{HEAD},sonar0\n0,0,0,0,\n0.1,0.1,0,0,nan\n"),
        "the log holds no range readings",
    ),
    (
        "every reading below the minimum range",
        lambda t: csv_log(t, f"{HEAD},sonar0\n0,0,0,0,0.1\n0.1,0.1,0,0,0.12\n"),
        "none of the 2 range readings can be mapped (2 below their sensor's minimum range)",
    ),
    (
        "a sensor the robot does not describe",
        lambda t: csv_log(t, f"{HEAD},front\n0,0,0,0,1\n0.1,0.1,0,0,1.2\n"),
        "no column is a range sensor of robot 'p3at' (columns front; the robot has "
        "sonar0..sonar15): give --robot",
    ),
    (
        "laser beams and a robot without a laser",
        lambda t: csv_log(t, f"{HEAD},laser1_0\n0,0,0,0,1\n0.1,0.1,0,0,1.2\n"),
        "no column is a range sensor of robot 'p3at' (columns laser1_0; the robot has",
    ),
    (
        "no robot for the sensors",
        lambda t: csv_log(t, "time,x,y,theta,sonar0\n0,0,0,0,1\n0.1,0.1,0,0,1.2\n"),
        "the log does not describe sensor 'sonar0'; give --robot",
    ),
    (
        "ARIA sonar without sonarUnit lines and no robot",
        lambda t: aria_log(t, SONAR_NO_UNITS),
        "the log does not describe sensors 'sonar0', 'sonar1'; give --robot",
    ),
    (
        "absurd coordinates",
        lambda t: csv_log(t, f"{HEAD},sonar0\n0,0,0,0,1\n0.1,1e9,0,0,1.2\n"),
        "the data spans 1e+09 m x 1.25 m",
    ),
    (
        "readings outside the odometry's time span",
        lambda t: mcap_log(t, 5.0),
        "no odometry during the range readings: the 3 readings span 5.000 s to 5.200 s (0.2 s), "
        "the odometry 1.000 s to 2.000 s (1.0 s) (recorded at different times?)",
    ),
    (
        "no odometry",
        lambda t: mcap_log(t, 1.0, odometry=False),
        "no odometry: no nav_msgs/Odometry, geometry_msgs/PoseStamped or gridmap.Pose2D topic "
        "and no TF; topics: /tf_static",
    ),
]


@pytest.mark.parametrize(
    ("make", "reason"), [(m, r) for _, m, r in BUILD_FAILS], ids=[n for n, _, _ in BUILD_FAILS]
)
def test_inspect_fails_with_builds_own_error(
    tmp_path: Path, make: Callable[[Path], Path], reason: str
) -> None:
    """Whenever build refuses a log, inspect says so, exits 1 as build does, and gives build's
    own error: on stderr as build prints it, as the text's last line and in the JSON."""
    log = make(tmp_path)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    code, _, err = run("build", str(log), "-o", str(out_dir / "map.png"))
    assert code == 1
    error = err.strip()
    assert error.startswith("Error: ") and "\n" not in error
    assert reason in error
    assert names(out_dir) == set()  # build wrote nothing
    message = error.removeprefix("Error: ")

    code, out, err = run("inspect", str(log))
    assert (code, err.strip()) == (1, error)
    lines = out.splitlines()
    assert lines[0].startswith(f"{log}: ")  # the description is printed all the same
    assert "What build would use:" in lines
    shown = message.removeprefix(f"{log}: ").split("; topics: ")[0]
    assert lines[-1] == f"  -> build would fail: {shown}"
    assert "ready to build" not in out

    code, out, err = run("inspect", str(log), "--json")
    assert (code, err.strip()) == (1, error)
    build = json.loads(out)["build"]
    assert (build["ready"], build["problem"]) == (False, message)


def test_giving_the_missing_robot_makes_the_log_ready(tmp_path: Path) -> None:
    log = aria_log(tmp_path, SONAR_NO_UNITS)
    d = inspect_json(str(log), "--robot", "p3at")
    assert (d["build"]["ready"], d["build"]["problem"]) == (True, None)
    code, out, err = run("inspect", str(log), "--robot", "p3at")
    assert (code, err, out.splitlines()[-1]) == (0, "", "  -> ready to build")


# ------------------------------------------------------------------------ a laser's real range

LASER = (
    "gridmap-robot: 1\nname: scanner\nsensors:\n"
    "  - {name: laser1, kind: laser, x_m: 0.2, y_m: 0.0, yaw_deg: 0, first_deg: -90, "
    "last_deg: 90, samples: 181, min_range_m: 0.02, max_range_m: 8.0}\n"
)


def laser_csv(tmp_path: Path) -> Path:
    (tmp_path / "scanner.yaml").write_text(LASER)
    beams = ",".join(f"laser1_{i}" for i in range(181))
    rows = "".join(f"{k / 10},{k / 10},0,0," + ",".join(["2.5"] * 180 + ["inf"]) + "\n"
                   for k in range(3))  # fmt: skip
    return csv_log(tmp_path, f"# robot: scanner.yaml\ntime,x,y,theta,{beams}\n{rows}")


def test_a_lasers_range_is_shown_for_csv_and_aria(tmp_path: Path) -> None:
    """The laser's range as build will use it: from the robot for a CSV log, from the log's
    sick1minRange/sick1maxRange lines once converted to ARIA."""
    csv = laser_csv(tmp_path)
    lasers = inspect_json(str(csv))["build"]["lasers"]
    assert lasers == [{"laser": "laser1", "beams": 181, "min_range_m": 0.02,
                       "max_range_m": 8.0, "range_from": "robot"}]  # fmt: skip
    assert "  laser     laser1: 181 beams, 0.02-8 m (from the robot)" in text_lines(csv)
    aria = tmp_path / "run.2d"
    code, _, err = run("convert", str(csv), str(aria), "-q")
    assert code == 0, err
    d = inspect_json(str(aria))
    assert d["build"]["lasers"] == [{**lasers[0], "range_from": "log"}]
    assert d["log"]["readings"]["no_echo"] == 3  # the last beam's 'inf', kept by the .2d
    assert "  laser     laser1: 181 beams, 0.02-8 m" in text_lines(aria)


def test_an_aria_log_without_range_lines_says_the_range_is_assumed(tmp_path: Path) -> None:
    log = aria_log(
        tmp_path,
        "LaserOdometryLog\nversion: 2\nsick1pose: 0 0 0\nsick1conf: -90 90 3\n"
        "time: 1.5\nrobot: 1000 -500 45\nsick1: 1000 0 2500\n",
    )
    d = inspect_json(str(log))
    assert d["build"]["lasers"] == [{"laser": "laser1", "beams": 3, "min_range_m": 0.0,
                                     "max_range_m": 32.0, "range_from": "assumed"}]  # fmt: skip
    assert "  laser     laser1: 3 beams, 0-32 m (the log gives no range: gridmap's default)" in (
        text_lines(log)
    )


def test_a_laserscans_range_is_shown_for_mcap(tmp_path: Path) -> None:
    path = tmp_path / "scan.mcap"
    with Recording(path) as rec:
        static_tf(rec, rec.transform(0, "base_link", "laser", 0.2, 0.0, 0.0))
        drive(rec)
        scan = {
            "header": rec.header(S, "laser"),
            "angle_min": -0.5,
            "angle_max": 0.5,
            "angle_increment": 0.25,
            "range_min": 0.05,
            "range_max": 5.5,
            "ranges": [1.0, 8.0, 2.0, math.inf, 3.0],
        }
        rec.write("/scan", "sensor_msgs/LaserScan", S, scan)
    d = inspect_json(str(path))
    assert d["build"]["lasers"] == [{"laser": "laser", "beams": 5, "min_range_m": 0.05,
                                     "max_range_m": 5.5, "range_from": "log"}]  # fmt: skip
    assert "  laser     laser: 5 beams, 0.05-5.5 m" in text_lines(path)


def test_a_long_log_header_is_one_key_a_line_wrapped_to_the_text_width() -> None:
    from gridmap_cli.describe.report import TEXT_WIDTH, header_lines

    long = "the chain of the increments between 14541 ODOM lines, " * 4
    lines = header_lines({"odometry": long.strip(), "skipped": "NEFF 910", "x": ""})
    assert lines[0] == "Log header:"
    assert all(len(line) <= TEXT_WIDTH for line in lines)
    assert lines[1].startswith("  odometry  the chain of") and lines[2].startswith(" " * 12 + "b")
    assert "  skipped   NEFF 910" in lines and "  x" in lines
    # the wrapped lines hold the value, word for word
    value = " ".join(line[12:] for line in lines[1:] if not line.startswith(("  skipped", "  x")))
    assert value == long.strip()
    assert header_lines({"robot": "p3at", "seed": "7"}) == ["Log header: robot: p3at, seed: 7"]


@pytest.mark.skipif(not CARMEN.is_dir(), reason="../shared/data/carmen is not present")
def test_a_carmen_logs_header_is_readable() -> None:
    code, out, _ = run("inspect", str(CARMEN / "intel-corrected.log.gz"))
    assert code == 0
    lines = out.splitlines()
    start = lines.index("Log header:")
    block = lines[start + 1 : lines.index("", start)]
    assert [line.split()[0] for line in block if not line.startswith("   ")] == [
        "odometry", "truth", "carmen", "stamps", "frontlaser", "skipped",
    ]  # fmt: skip
    assert max(len(line) for line in lines) <= 100 + len(str(CARMEN))
