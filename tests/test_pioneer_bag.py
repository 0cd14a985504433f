"""`gridmap build BAG --pose slam` on the ROS 1 bag a Pioneer running ROSARIA and a SICK driver
records (issue 20): a simulated loop with poor odometry, written by ``rosbags``' ROS 1 writer as
``rosbag record`` would (tests/readers/pioneer_bag.py), mapped with no topic flags and scored
against the world; and the one-line errors where the bag leaves a choice open."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.mapping.grid import OccupancyMap
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import load_robot
from gridmap_cli.sim.path import WaypointPath
from gridmap_cli.sim.simulate import simulate
from gridmap_cli.writers.csv_log import save_csv_log
from gridmap_cli.writers.map_image import write_map
from tests.helpers import run
from tests.readers.pioneer_bag import write_pioneer_bag
from tests.test_scan_match import room_world

LOOP = [[2, 1.5], [10, 1.5], [10, 6.5], [2, 6.5], [2, 1.5]]


@pytest.fixture(scope="module")
def pioneer(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, RangeLog]:
    """A folder with the world (world.yaml), the run as CSV with its truth (run.csv, which
    evaluate places maps by) and as a ROSARIA bag (run.bag)."""
    folder = tmp_path_factory.mktemp("pioneer")
    world = room_world()
    path = WaypointPath(waypoints=np.asarray(LOOP, dtype=np.float64), speed_m_s=0.5)
    log = simulate(world, path, load_robot("p3at-lms200"), seed=3, drift=3.0)
    log.metadata["robot"] = "p3at-lms200"
    save_csv_log(log, folder / "run.csv")
    occupied = OccupancyMap(world.spec, world.occupied.astype(np.float64))
    write_map(folder / "world.pgm", occupied, mode="trinary")
    write_pioneer_bag(log, folder / "run.bag")
    return folder, log


def f1(folder: Path, bag: Path, pose: str, *extra: str) -> float:
    """``build BAG --pose POSE`` (laser only: the sonar is not in the bag) scored by evaluate."""
    out = folder / f"{bag.stem}-{pose}.png"
    code, _, stderr = run("build", str(bag), "--pose", pose, "-o", str(out), "--map-mode",
                          "scale", "--force", *extra)  # fmt: skip
    assert code == 0, stderr
    code, stdout, stderr = run("evaluate", str(out.with_suffix(".yaml")), "--truth",
                               str(folder / "world.yaml"), "--log", str(folder / "run.csv"),
                               "--pose", pose, "--json")  # fmt: skip
    assert code == 0, stderr
    return float(json.loads(stdout)["f1"])


def test_slam_maps_a_rosaria_bag_where_odometry_cannot(pioneer: tuple[Path, RangeLog]) -> None:
    folder, _ = pioneer
    bag = folder / "run.bag"
    odometry, slam = f1(folder, bag, "odometry"), f1(folder, bag, "slam")
    assert odometry < 0.5
    assert slam >= 0.70 and slam > odometry + 0.3


def test_the_laser_frame_is_found_with_or_without_a_slash_and_without_tf(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    """ROS 1 drivers spell frames `/laser` or `laser`; a bag with no base_link -> laser
    transform takes the robot file's one laser (named `laser1` there, not `laser`)."""
    _, log = pioneer
    tracks = []
    for name, options in (
        ("plain", {}),
        ("slash", {"laser_frame": "/laser"}),
        ("untransformed", {"mounting": None}),
    ):
        bag = write_pioneer_bag(log, tmp_path / f"{name}.bag", **options)  # type: ignore[arg-type]
        out = tmp_path / f"{name}.tum"
        robot = ("--robot", "p3at-lms200") if name == "untransformed" else ()
        code, _, stderr = run("trajectory", str(bag), "--pose", "slam", "-o", str(out), *robot)
        assert code == 0, stderr
        tracks.append(np.loadtxt(out))
    plain, slash, untransformed = tracks
    assert np.array_equal(slash, plain)
    # the robot file's beam directions are whole degrees, the scan's float32 angles are not:
    # the same track to within what that changes in the matcher
    assert np.abs(untransformed[:, 1:3] - plain[:, 1:3]).max() < 0.05


def test_a_laser_with_no_mounting_anywhere_is_refused_in_one_line(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    _, log = pioneer
    bag = write_pioneer_bag(log, tmp_path / "bare.bag", mounting=None)
    out = tmp_path / "map.png"
    code, _, stderr = run("build", str(bag), "--pose", "slam", "-o", str(out), "--robot", "p3at")
    assert code == 1
    assert stderr.strip().splitlines() == [
        f"Error: {bag}: sensor frame 'laser' (/scan): mounting pose unknown: no transform from "
        "'base_link' to it on /tf, and robot 'p3at' has no laser named 'laser': give its pose "
        "on 'base_link' with --laser-mount X,Y,YAW_DEG (metres, degrees), or --robot FILE "
        "holding the two lines 'gridmap-robot: 1' and 'sensors: [{name: laser, kind: laser, "
        "x_m: X, y_m: Y, yaw_deg: YAW_DEG}]' (its beams and range come from the scans; "
        "docs/robot-format.md)"
    ]
    assert not out.exists() and not out.with_suffix(".yaml").exists()


def test_from_python_an_unmounted_laser_names_the_read_option_in_radians(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    """The flag takes degrees; the Python read option takes radians, and the error says so."""
    from gridmap_cli import GridmapError, read_log

    _, log = pioneer
    bag = write_pioneer_bag(log, tmp_path / "bare.bag", mounting=None)
    with pytest.raises(GridmapError) as caught:
        read_log(bag)
    message = str(caught.value)
    assert "ReadOptions(laser_mount=(X, Y, YAW_RAD)) (metres, radians)" in message
    assert "no robot describing it" in message and "robot='FILE'" in message
    assert "--" not in message


def test_a_bag_without_tf_for_its_laser_maps_with_one_flag_or_a_two_line_robot_file(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    """The scans give the beams (angles, count, range): the mounting alone is missing, and
    either way of giving it maps the bag exactly as its TF mounting does."""
    _, log = pioneer
    bare = write_pioneer_bag(log, tmp_path / "bare.bag", mounting=None)
    with_tf = write_pioneer_bag(log, tmp_path / "tf.bag", mounting=(0.16, 0.0, 0.0))
    robot = tmp_path / "laser.yaml"
    robot.write_text(
        "gridmap-robot: 1\nsensors: [{name: laser, kind: laser, x_m: 0.16, y_m: 0, yaw_deg: 0}]\n"
    )
    maps = {}
    for name, bag, extra in (
        ("tf", with_tf, ()),
        ("flag", bare, ("--laser-mount", "0.16,0,0")),
        ("file", bare, ("--robot", str(robot))),
    ):
        out = tmp_path / f"{name}.pgm"
        code, _, stderr = run("build", str(bag), "-o", str(out), "--quiet", *extra)
        assert code == 0, stderr
        maps[name] = out.read_bytes()
    assert maps["flag"] == maps["tf"] and maps["file"] == maps["tf"]
    described = json.loads(run("inspect", str(bare), "--laser-mount", "0.16,0,0", "--json")[1])
    assert described["build"]["ready"]
    assert {s["mounting_from"] for s in described["log"]["sensors"]} == {"--laser-mount"}


def test_a_robot_laser_of_another_beam_count_is_refused_naming_both_counts(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    _, log = pioneer
    bag = write_pioneer_bag(log, tmp_path / "bare.bag", mounting=None)
    robot = tmp_path / "bot.yaml"
    robot.write_text(
        "gridmap-robot: 1\nname: bot\nsensors:\n  - {name: laser, kind: laser, x_m: 0.16, "
        "y_m: 0, yaw_deg: 0, first_deg: -90, last_deg: 90, samples: 180, max_range_m: 8}\n"
    )
    out = tmp_path / "map.png"
    code, _, stderr = run("build", str(bag), "-o", str(out), "--robot", str(robot))
    assert code == 1
    assert stderr.strip().splitlines() == [
        f"Error: {bag}: sensor frame 'laser' (/scan): mounting pose unknown: no transform from "
        "'base_link' to it on /tf, and robot 'bot' describes laser 'laser' with 180 beams where "
        "the scans on /scan have 181: leave first_deg, last_deg and samples out of its entry and "
        "the scans give them"
    ]
    assert not out.exists() and not out.with_suffix(".yaml").exists()


def test_a_bad_laser_mount_is_a_usage_error(pioneer: tuple[Path, RangeLog], tmp_path: Path) -> None:
    folder, _ = pioneer
    out = tmp_path / "map.png"
    for value in ("0.16,0", "a,b,c", "0,0,nan"):
        code, _, stderr = run("build", str(folder / "run.bag"), "-o", str(out), "--laser-mount",
                              value)  # fmt: skip
        assert code == 2 and "--laser-mount" in stderr and stderr.count("\n") <= 3, stderr
    code, _, stderr = run("build", str(folder / "run.csv"), "-o", str(out), "--laser-mount",
                          "0.16,0,0")  # fmt: skip
    assert (code, stderr.strip()) == (
        2, "Error: --laser-mount only applies to ROS recordings (MCAP, bag, rosbag2), not to CSV "
        "logs"
    )  # fmt: skip
    assert not out.exists()


def test_two_odometry_topics_are_an_error_naming_both(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    _, log = pioneer
    bag = write_pioneer_bag(log, tmp_path / "two.bag", second_odometry="/odom")
    out = tmp_path / "map.png"
    code, _, stderr = run("build", str(bag), "--pose", "slam", "-o", str(out))
    assert code != 0
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: ")
    assert "/RosAria/pose" in lines[0] and "/odom" in lines[0] and "--odom-topic" in lines[0]
    assert not out.exists()
    code, _, stderr = run("build", str(bag), "--pose", "slam", "-o", str(out), "--odom-topic",
                          "/RosAria/pose", "--quiet")  # fmt: skip
    assert code == 0, stderr


def test_rosaria_sonar_without_a_robot_names_both_ways_out(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    """RosAria's sonar cloud cannot be placed without the robot's sonar ring: the error says
    to give it, or to map the laser alone; either then builds."""
    folder, log = pioneer
    bag = write_pioneer_bag(log, tmp_path / "sonar.bag", sonar=True)
    out = tmp_path / "map.png"
    code, _, stderr = run("build", str(bag), "--pose", "slam", "-o", str(out))
    assert code == 1
    assert stderr.strip().splitlines() == [
        f"Error: {bag}: /RosAria/sonar: sonar point clouds (as RosAria publishes them) need the "
        "sonar positions: give --robot (a preset, robot YAML or ARIA .p file), or --range-topic "
        "/scan to map the laser alone"
    ]
    assert not out.exists()
    assert f1(folder, bag, "slam", "--range-topic", "/scan") >= 0.70


@pytest.mark.parametrize("range_max", [float("nan"), float("inf")])
def test_a_scan_without_a_finite_range_max_is_refused_in_one_line(
    pioneer: tuple[Path, RangeLog], tmp_path: Path, range_max: float
) -> None:
    _, log = pioneer
    bag = write_pioneer_bag(log, tmp_path / "bad.bag", range_max=range_max)
    out = tmp_path / "map.png"
    code, _, stderr = run("build", str(bag), "-o", str(out))
    assert code == 1 and stderr.count("\n") == 1, stderr
    assert stderr.startswith(f"Error: {bag}: /scan at log time ")
    assert stderr.strip().endswith(
        f"laser 'laser': need 0 <= range_min < range_max, range_max finite, got 0.0 and {range_max}"
    )
    assert not out.exists() and not out.with_suffix(".yaml").exists()


def slam_track(bag: Path, *extra: str) -> np.ndarray:
    """``trajectory BAG --pose slam`` (beside the bag, as TUM rows), read back."""
    out = bag.with_suffix(".tum")
    code, _, stderr = run("trajectory", str(bag), "--pose", "slam", "-o", str(out), *extra)
    assert code == 0, stderr
    return np.loadtxt(out)


def mountings_from(bag: Path, *extra: str) -> set[str]:
    """Where ``inspect`` says the bag's sensors got their mountings."""
    code, stdout, stderr = run("inspect", str(bag), "--json", *extra)
    assert code == 0, stderr
    return {s["mounting_from"] for s in json.loads(stdout)["log"]["sensors"]}


def test_a_laser_mounted_upside_down_maps_as_an_upright_one(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    """A laser under a deck, TF rolling it by pi, sweeps the world right to left: its beams
    are mirrored into the robot's frame, so the track and the map are the upright laser's."""
    folder, log = pioneer
    upright = slam_track(write_pioneer_bag(log, tmp_path / "upright.bag"))
    bag = write_pioneer_bag(log, tmp_path / "under.bag", laser_tilt=(0.0, np.pi))
    under = slam_track(bag)
    # the same world, but the writer's odd beams without echo fall on other beams once the
    # scan is reversed: the same track to within what that changes in the matcher
    assert np.abs(under[:, 1:3] - upright[:, 1:3]).max() < 0.05
    assert f1(folder, bag, "slam") >= 0.70
    assert mountings_from(bag) == {"TF, upside down"}


def test_a_robot_file_mounts_a_laser_upside_down_where_tf_does_not(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    """A bag without the laser's TF whose laser hangs upside down: the two-line robot file
    with ``upside_down: true`` gives the track the TF-mounted bag gives."""
    _, log = pioneer
    under = write_pioneer_bag(log, tmp_path / "under.bag", laser_tilt=(0.0, np.pi))
    bare = write_pioneer_bag(log, tmp_path / "bare.bag", mounting=None, laser_tilt=(0.0, np.pi))
    robot = tmp_path / "robot.yaml"
    robot.write_text(
        "gridmap-robot: 1\nsensors: [{name: laser, kind: laser, x_m: 0.16, y_m: 0.0, "
        "yaw_deg: 0, upside_down: true}]\n"
    )
    assert np.array_equal(slam_track(under), slam_track(bare, "--robot", str(robot)))
    assert mountings_from(bare, "--robot", str(robot)) == {"robot, upside down"}


def test_a_laser_sweeping_clockwise_reads_as_the_same_beams(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    """A driver that sends each scan from its left end (a negative angle_increment): the same
    directions, so the same track."""
    _, log = pioneer
    anticlockwise = slam_track(write_pioneer_bag(log, tmp_path / "anticlockwise.bag"))
    clockwise = slam_track(write_pioneer_bag(log, tmp_path / "clockwise.bag", clockwise=True))
    # the writer's odd beams without echo fall on other beams of the reversed scan
    assert np.abs(clockwise[:, 1:3] - anticlockwise[:, 1:3]).max() < 0.05


def test_a_multi_echo_laser_maps_by_its_first_echoes(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    """sensor_msgs/MultiEchoLaserScan (a second echo 1.5 m behind each first one, no echo
    where the single-echo scan has NaN): the map of the single-echo bag, byte for byte; inspect
    lists it as the laser's range readings."""
    _, log = pioneer
    maps = []
    for name, multi in (("single", False), ("multi", True)):
        bag = write_pioneer_bag(log, tmp_path / f"{name}.bag", multi_echo=multi)
        out = tmp_path / f"{name}.pgm"
        code, _, stderr = run("build", str(bag), "-o", str(out), "--quiet")
        assert code == 0, stderr
        maps.append(out.read_bytes())
    assert maps[0] == maps[1]
    code, stdout, stderr = run("inspect", str(tmp_path / "multi.bag"), "--json")
    assert code == 0, stderr
    described = json.loads(stdout)
    channels = {c["topic"]: c for c in described["mcap"]["channels"]}
    assert channels["/scan"]["type"] == "sensor_msgs/MultiEchoLaserScan"
    assert channels["/scan"]["used_as"] == "range readings"
    assert described["build"]["lasers"][0]["beams"] == 181
    # a multi-echo laser alone (no odometry: a backpack's) takes its motion from its scans
    alone = write_pioneer_bag(log, tmp_path / "alone.bag", multi_echo=True, odometry=False)
    code, _, stderr = run("build", str(alone), "-o", str(tmp_path / "alone.pgm"))
    assert code == 0, stderr
    assert "no odometry: motion from the scans" in stderr
    assert {s["mounting_from"] for s in described["log"]["sensors"]} == {"TF"}


def test_beams_of_exactly_zero_are_no_reading(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    """A driver with range_min 0 that writes 0 for a beam that read nothing: those beams are
    neither mapped nor matched (they were echoes at the laser's own position)."""
    _, log = pioneer
    summaries = []
    for name, zeros in (("plain", 0.0), ("zeros", 0.1)):
        bag = write_pioneer_bag(log, tmp_path / f"{name}.bag", zeros=zeros)
        out = tmp_path / f"{name}.png"
        code, stdout, stderr = run("build", str(bag), "--pose", "odometry", "-o", str(out),
                                   "--json")  # fmt: skip
        assert code == 0, stderr
        summaries.append(json.loads(stdout)["readings"])
    plain, zeros = summaries
    # about a tenth of the beams fewer, every one of the rest mapped
    assert 0.85 * plain["total"] < zeros["total"] < 0.95 * plain["total"]
    assert zeros["used"] == zeros["total"]


@pytest.mark.parametrize("pitch_deg", [60.0, 90.0])
def test_a_laser_tilted_out_of_level_is_refused_in_one_line(
    pioneer: tuple[Path, RangeLog], tmp_path: Path, pitch_deg: float
) -> None:
    _, log = pioneer
    tilt = (float(np.radians(pitch_deg)), 0.0)
    bag = write_pioneer_bag(log, tmp_path / "tilted.bag", laser_tilt=tilt)
    out = tmp_path / "map.png"
    code, _, stderr = run("build", str(bag), "-o", str(out))
    assert code == 1 and stderr.count("\n") == 1, stderr
    assert stderr.strip().endswith(
        f"laser 'laser' (/scan): TF tilts its scan plane {pitch_deg:.0f} degrees from the plane "
        "of 'base_link': gridmap maps lasers that scan level (upright or upside down)"
    )
    assert not out.exists() and not out.with_suffix(".yaml").exists()


def test_a_vertical_laser_beside_a_level_one_is_refused_naming_the_topics_to_map_with(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    """A backpack's pair: a level laser and one TF pitches 90 degrees. The refusal says how to
    map without the vertical one, and that way maps as the level laser alone does."""
    _, log = pioneer
    bag = write_pioneer_bag(log, tmp_path / "pair.bag", vertical=True)
    out = tmp_path / "pair.pgm"
    code, _, stderr = run("build", str(bag), "-o", str(out))
    assert code == 1 and stderr.count("\n") == 1, stderr
    assert stderr.strip().endswith(
        "laser 'vertical_laser' (/vertical_scan): TF tilts its scan plane 90 degrees from the "
        "plane of 'base_link': gridmap maps lasers that scan level (upright or upside down); "
        "map without it: --range-topic /scan"
    )
    assert not out.exists()
    code, _, stderr = run("build", str(bag), "-o", str(out), "--range-topic", "/scan", "--quiet")
    assert code == 0, stderr
    alone = tmp_path / "alone.pgm"
    code, _, stderr = run("build", str(write_pioneer_bag(log, tmp_path / "alone.bag")), "-o",
                          str(alone), "--quiet")  # fmt: skip
    assert code == 0, stderr
    assert out.read_bytes() == alone.read_bytes()
