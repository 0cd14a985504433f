"""`gridmap simulate` as a user meets it: the log it writes, determinism, and one-line errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.mapping.grid import GridSpec, OccupancyMap
from gridmap_cli.readers.text.csv_log import read_csv_log
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import load_robot, preset_names
from gridmap_cli.writers.map_image import write_map
from tests.helpers import names, run

RES_M = 0.05
ROOM_W_M, ROOM_H_M = 4.0, 3.0
WALL_CELLS = 2  # 10 cm walls along the edge of the grid
INNER_M = WALL_CELLS * RES_M  # where the free space begins, from each edge

# Three waypoints: a 2 m leg along +x, a 90 degree turn in place, a 1 m leg along +y.
WAYPOINTS = [(1.0, 1.0), (3.0, 1.0), (3.0, 2.0)]
PATH_YAML = "gridmap-path: 1\nwaypoints:\n" + "".join(f"  - [{x}, {y}]\n" for x, y in WAYPOINTS)


@pytest.fixture
def world(tmp_path: Path) -> Path:
    """A 4 m x 3 m room, walls on the grid's border, written as a map_server map."""
    spec = GridSpec(0.0, 0.0, RES_M, round(ROOM_W_M / RES_M), round(ROOM_H_M / RES_M))
    prob = np.zeros(spec.shape)
    prob[:WALL_CELLS, :] = prob[-WALL_CELLS:, :] = 1.0
    prob[:, :WALL_CELLS] = prob[:, -WALL_CELLS:] = 1.0
    _, yaml_path = write_map(tmp_path / "room.pgm", OccupancyMap(spec, prob))
    return yaml_path


@pytest.fixture
def path_file(tmp_path: Path) -> Path:
    path = tmp_path / "path.yaml"
    path.write_text(PATH_YAML)
    return path


def simulate(world: Path, path_file: Path, out: Path, *options: str) -> RangeLog:
    code, stdout, stderr = run("simulate", str(world), str(path_file), "-o", str(out), *options)
    assert code == 0, stderr
    assert stdout == ""
    return read_csv_log(out)


# --- the log -------------------------------------------------------------------------------------


def test_simulate_writes_a_log_the_reader_reads(
    world: Path, path_file: Path, tmp_path: Path
) -> None:
    out = tmp_path / "sim.csv"
    code, stdout, stderr = run(
        "simulate", str(world), str(path_file), "-o", str(out), "--seed", "5", "--drift", "0.5"
    )
    assert code == 0 and stdout == ""
    # one summary line, naming the output
    assert len(stderr.splitlines()) == 1
    assert stderr.startswith("gridmap: simulated ") and stderr.rstrip().endswith(f"-> {out}")

    log = read_csv_log(out)
    assert log.metadata == {
        "gridmap-csv": "1",
        "robot": "p3at",
        "seed": "5",
        "drift": "0.5",
        "rate": "10.0",
        "world": str(world),
        "path": str(path_file),
    }
    p3at = load_robot("p3at")
    assert len(log.sensor_names) == 16
    assert log.sensor_names == p3at.names()
    n = len(log.poses)
    # every sonar reads at every pose
    assert len(log.readings) == 16 * n
    assert log.readings.sensor.tolist() == list(range(16)) * n
    # time from 0 in steps of exactly 0.1 s at 10 Hz
    assert log.poses.stamp_ns[0] == 0
    assert set(np.diff(log.poses.stamp_ns).tolist()) == {100_000_000}
    # 2 m + 1 m at 0.4 m/s and a 90 degree turn at 40 deg/s: the run takes 9.75 s and the last
    # sample is the last one at or before its end
    end_ns = round((3.0 / 0.4 + 90.0 / 40.0) * 1e9)
    assert log.poses.stamp_ns[-1] <= end_ns < log.poses.stamp_ns[-1] + 100_000_000

    truth = log.truth
    assert truth is not None
    np.testing.assert_array_equal(truth.stamp_ns, log.poses.stamp_ns)
    # truth starts on the first waypoint, facing the second; odometry starts at its own origin
    assert (truth.x_m[0], truth.y_m[0], truth.theta_rad[0]) == (1.0, 1.0, 0.0)
    assert (log.poses.x_m[0], log.poses.y_m[0], log.poses.theta_rad[0]) == (0.0, 0.0, 0.0)
    # every true pose lies on the two legs, and the last is within one step of the goal
    on_first = np.isclose(truth.y_m, 1.0) & (truth.x_m >= 1.0) & (truth.x_m <= 3.0)
    on_second = np.isclose(truth.x_m, 3.0) & (truth.y_m >= 1.0) & (truth.y_m <= 2.0)
    assert np.all(on_first | on_second)
    assert math.hypot(truth.x_m[-1] - 3.0, truth.y_m[-1] - 2.0) <= 0.4 / 10 + 1e-9


def test_sonar_ranges_match_the_room(world: Path, path_file: Path, tmp_path: Path) -> None:
    log = simulate(world, path_file, tmp_path / "sim.csv", "--quiet")
    p3at = load_robot("p3at")
    max_range = p3at.sensors[0].max_range_m
    ranges = log.readings.range_m.reshape(len(log.poses), 16)
    assert np.all(ranges > 0.0) and np.all(ranges <= max_range)
    # inside a closed room most beams hear a wall
    assert np.mean(ranges < max_range) > 0.5
    # At the start (1, 1) facing +x, the side sonars look straight at the walls y = 0.1 and
    # y = 2.9 (inner faces): the reading is that distance with about 1 % noise.
    by_name = p3at.by_name()
    left, right = by_name["sonar0"], by_name["sonar7"]
    assert left.yaw_rad == pytest.approx(math.pi / 2)
    assert right.yaw_rad == pytest.approx(-math.pi / 2)
    to_left_wall = (ROOM_H_M - INNER_M) - (1.0 + left.y_m)
    to_right_wall = (1.0 + right.y_m) - INNER_M
    assert ranges[0, 0] == pytest.approx(to_left_wall, rel=0.04)
    assert ranges[0, 7] == pytest.approx(to_right_wall, rel=0.04)


def test_quiet_prints_nothing(world: Path, path_file: Path, tmp_path: Path) -> None:
    code, stdout, stderr = run(
        "simulate", str(world), str(path_file), "-o", str(tmp_path / "q.csv"), "-q"
    )
    assert (code, stdout, stderr) == (0, "", "")
    assert (tmp_path / "q.csv").is_file()


def test_rate_sets_the_time_step(world: Path, path_file: Path, tmp_path: Path) -> None:
    log = simulate(world, path_file, tmp_path / "r.csv", "--rate", "4", "-q")
    assert log.poses.stamp_ns[0] == 0
    assert set(np.diff(log.poses.stamp_ns).tolist()) == {250_000_000}


def test_same_seed_same_bytes_different_seed_different_bytes(
    world: Path, path_file: Path, tmp_path: Path
) -> None:
    # the same file name each time, so the metadata lines agree too
    outs = []
    for i, seed in enumerate(["7", "7", "8"]):
        folder = tmp_path / f"run{i}"
        folder.mkdir()
        simulate(world, path_file, folder / "sim.csv", "--seed", seed, "-q")
        outs.append((folder / "sim.csv").read_bytes())
    assert outs[0] == outs[1]
    assert outs[0] != outs[2]
    a = read_csv_log(tmp_path / "run0" / "sim.csv")
    c = read_csv_log(tmp_path / "run2" / "sim.csv")
    assert a.truth is not None and c.truth is not None
    # the seed changes the errors, never where the robot really went
    np.testing.assert_array_equal(a.truth.x_m, c.truth.x_m)
    np.testing.assert_array_equal(a.truth.theta_rad, c.truth.theta_rad)
    assert not np.array_equal(a.poses.x_m, c.poses.x_m)
    assert not np.array_equal(a.readings.range_m, c.readings.range_m)


def truth_relative_to_start(log: RangeLog) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The true poses expressed in the frame of the first true pose: inverse(T0) (+) Tk."""
    t = log.truth
    assert t is not None
    c, s = math.cos(t.theta_rad[0]), math.sin(t.theta_rad[0])
    dx, dy = t.x_m - t.x_m[0], t.y_m - t.y_m[0]
    dth = np.remainder(t.theta_rad - t.theta_rad[0] + math.pi, 2 * math.pi) - math.pi
    return c * dx + s * dy, -s * dx + c * dy, dth


def angle_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(np.remainder(a - b + math.pi, 2 * math.pi) - math.pi)


def test_drift_zero_gives_odometry_equal_to_truth_from_its_start(
    world: Path, tmp_path: Path
) -> None:
    # start facing 30 degrees off the first leg, so the odometry frame is really rotated
    path = tmp_path / "tilted.yaml"
    path.write_text(PATH_YAML + "start_heading_deg: 30\n")
    perfect = simulate(world, path, tmp_path / "perfect.csv", "--drift", "0", "-q")
    x, y, th = truth_relative_to_start(perfect)
    assert perfect.truth is not None and perfect.truth.theta_rad[0] == pytest.approx(
        math.radians(30)
    )
    # logs hold poses at 1 mm and 0.01 degree (both the odometry and the truth are rounded, and
    # the truth's first pose too): the two agree to within that resolution
    mm, centideg = 1e-3, np.radians(0.01)
    np.testing.assert_allclose(perfect.poses.x_m, x, rtol=0, atol=1.5 * mm + 5 * centideg)
    np.testing.assert_allclose(perfect.poses.y_m, y, rtol=0, atol=1.5 * mm + 5 * centideg)
    assert np.max(angle_error(perfect.poses.theta_rad, th)) <= 1.01 * centideg

    # the same comparison at drift 1 shows the drift: the check above is not vacuous
    drifting = simulate(world, path, tmp_path / "drift.csv", "--drift", "1", "-q")
    x, y, th = truth_relative_to_start(drifting)
    end_error = math.hypot(drifting.poses.x_m[-1] - x[-1], drifting.poses.y_m[-1] - y[-1])
    assert end_error > 1e-3
    assert angle_error(drifting.poses.theta_rad[-1:], th[-1:])[0] > 1e-4


def test_build_maps_the_simulated_log(world: Path, path_file: Path, tmp_path: Path) -> None:
    log_path = tmp_path / "sim.csv"
    log = simulate(world, path_file, log_path, "--drift", "0", "-q")
    out = tmp_path / "map.png"
    code, stdout, stderr = run("build", str(log_path), "-o", str(out), "--json", "-q")
    assert code == 0, stderr
    summary = json.loads(stdout)
    assert summary["readings"]["total"] == len(log.readings)
    assert summary["readings"]["outside_odometry"] == 0
    assert summary["readings"]["used"] > 0.9 * len(log.readings)
    assert summary["cells"]["occupied"] > 0 and summary["cells"]["free"] > 0
    assert out.is_file() and (tmp_path / "map.yaml").is_file()
    # With perfect odometry the map's frame is the world's shifted to the start (1, 1), heading 0:
    # occupied cells lie along the four walls (sonar arcs blur corners a little), never in the
    # middle of the room.
    from gridmap_cli.mapping.mapfile import load_map

    loaded = load_map(tmp_path / "map.yaml")
    rows, cols = np.nonzero(loaded.occupancy == 100)
    x, y = loaded.spec.cell_center(cols, rows)
    wx, wy = x + 1.0, y + 1.0
    # depth of each occupied cell into the room from the inner faces of the walls
    # (negative: in or behind a wall)
    to_wall = np.stack(
        [wx - INNER_M, ROOM_W_M - INNER_M - wx, wy - INNER_M, ROOM_H_M - INNER_M - wy]
    )
    depth = to_wall.min(axis=0)
    assert rows.size > 100
    assert np.all(depth < 0.5)
    assert np.mean(depth < 0.15) > 0.9
    # and every wall shows up
    assert np.all((np.abs(to_wall) < 0.1).any(axis=1))


# --- errors --------------------------------------------------------------------------------------


def test_existing_output_needs_force(world: Path, path_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "sim.csv"
    out.write_text("keep me\n")
    code, stdout, stderr = run("simulate", str(world), str(path_file), "-o", str(out))
    assert (code, stdout) == (1, "")
    assert stderr == f"Error: {out} exists (use --force to overwrite)\n"
    assert out.read_text() == "keep me\n"
    assert names(tmp_path) == {"room.pgm", "room.yaml", "path.yaml", "sim.csv"}
    simulate(world, path_file, out, "--force", "-q")
    assert out.read_text().startswith("# gridmap-csv: 1\n")


@pytest.mark.parametrize("force", [[], ["--force"]])
def test_an_output_that_is_a_directory_is_refused_before_simulating(
    force: list[str], world: Path, path_file: Path, tmp_path: Path
) -> None:
    """writers.check_output refuses it in one line, a usage mistake (exit 2), with or without
    --force."""
    out = tmp_path / "sim.csv"
    out.mkdir()
    code, stdout, stderr = run("simulate", str(world), str(path_file), "-o", str(out), *force)
    assert (code, stdout) == (2, "")
    assert stderr == f"Error: {out} is a directory\n"
    assert names(out) == set()


def _bad_path_file(tmp_path: Path) -> Path:
    bad = tmp_path / "bad.yaml"
    bad.write_text("gridmap-path: 1\nwaypoints:\n  - [1.0, 1.0]\n  - [3.0, oops]\n")
    return bad


@pytest.mark.parametrize(
    ("case", "code"),
    [
        ("missing world", 1),
        ("missing path", 1),
        ("bad waypoint", 1),
        ("negative drift", 2),
        ("zero rate", 2),
        ("zero duration", 2),
        ("nan rate", 2),
        ("infinite drift", 2),
        ("nan duration", 2),
        ("missing world and unknown robot", 2),
        ("not csv", 2),
        ("unknown robot", 2),
    ],
)
def test_bad_input_gives_one_error_line_and_no_output(
    world: Path, path_file: Path, tmp_path: Path, case: str, code: int
) -> None:
    out = tmp_path / "sim.csv"
    w, p, extra = str(world), str(path_file), []
    robots = ", ".join(preset_names())
    expected = {
        "missing world": f"{tmp_path / 'nowhere.yaml'}: no such file",
        "missing path": f"{tmp_path / 'nowhere.yaml'}: no such file",
        "bad waypoint": f"{tmp_path / 'bad.yaml'}:4: waypoint 2 must be [x, y] in metres, "
        "got [3.0, 'oops']",
        "negative drift": "--drift must be a finite number >= 0, got -1.0",
        "zero rate": "--rate must be a positive number of Hz, got 0.0",
        "zero duration": "--duration must be a positive number of seconds, got 0.0",
        "nan rate": "--rate must be a positive number of Hz, got nan",
        "infinite drift": "--drift must be a finite number >= 0, got inf",
        "nan duration": "--duration must be a positive number of seconds, got nan",
        # the command line is checked before the files it names
        "missing world and unknown robot": f"unknown robot 'r2': not a preset ({robots}) and "
        "no such file",
        "not csv": f"{tmp_path / 'sim.txt'}: cannot tell the log format from the name; end it "
        "in one of csv (.csv), aria (.2d), mcap (.mcap) or give --to",
        "unknown robot": f"unknown robot 'r2': not a preset ({robots}) and no such file",
    }[case]
    if case == "missing world":
        w = str(tmp_path / "nowhere.yaml")
    elif case == "missing path":
        p = str(tmp_path / "nowhere.yaml")
    elif case == "bad waypoint":
        p = str(_bad_path_file(tmp_path))
    elif case == "negative drift":
        extra = ["--drift", "-1"]
    elif case == "zero rate":
        extra = ["--rate", "0"]
    elif case == "zero duration":
        extra = ["--duration", "0"]
    elif case == "nan rate":
        extra = ["--rate", "nan"]
    elif case == "infinite drift":
        extra = ["--drift", "inf"]
    elif case == "nan duration":
        extra = ["--duration", "nan"]
    elif case == "missing world and unknown robot":
        w, extra = str(tmp_path / "nowhere.yaml"), ["--robot", "r2"]
    elif case == "not csv":
        out = tmp_path / "sim.txt"
    elif case == "unknown robot":
        extra = ["--robot", "r2"]
    before = names(tmp_path)
    got, stdout, stderr = run("simulate", w, p, "-o", str(out), *extra)
    assert got == code
    assert stdout == ""
    assert stderr == f"Error: {expected}\n"
    assert names(tmp_path) == before, "nothing may be written for bad input"


def test_output_folder_must_exist(world: Path, path_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "no" / "sim.csv"
    code, _, stderr = run("simulate", str(world), str(path_file), "-o", str(out))
    assert code == 1
    assert stderr == f"Error: {out}: directory {out.parent} does not exist\n"
    assert not out.parent.exists()
