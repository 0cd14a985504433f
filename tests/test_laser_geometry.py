"""Lasers as they are: a LaserScan whose geometry changes from scan to scan (interleaved start
angles, a beam more or less) is read with each scan's own beams, and maps and matches as the same
laser with one geometry; a scan whose ranges do not fit its own angles is refused in one line;
and a laser recorded without odometry maps with ``--pose scan-matched`` and ``slam``, its motion
taken from the scans (the ROS 1 bags of tests/readers/pioneer_bag.py)."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.readers import read_log
from gridmap_cli.readers.ros.mcap import bulk as mcap_bulk
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import parse_robot_yaml
from gridmap_cli.sim.path import WaypointPath
from gridmap_cli.sim.simulate import simulate
from tests.helpers import run
from tests.readers.pioneer_bag import write_pioneer_bag
from tests.test_pioneer_bag import LOOP, f1, pioneer
from tests.test_scan_match import room_world

__all__ = ["pioneer"]  # the fixture, shared with tests/test_pioneer_bag.py

#: Start angles a turn of the interleaving laser goes through (a quarter step apart).
TURNS = 4


@pytest.fixture(scope="module")
def interleaved(
    pioneer: tuple[Path, RangeLog], tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, Path, Path]:
    """The Pioneer loop again, simulated with a laser four times as fine, written as a laser
    that sends 181 beams from -90 degrees, then 180 from a quarter step on, and so on (a turn
    of four start angles), and as the same laser with the first start angle always: the
    folder (with the pioneer's world and CSV), the interleaving bag and the constant one."""
    folder, _ = pioneer
    text = (Path(__file__).parents[1] / "gridmap_cli" / "presets" / "p3at-lms200.yaml").read_text()
    fine = parse_robot_yaml(text.replace("samples: 181", f"samples: {180 * TURNS + 1}"), "fine")
    path = WaypointPath(waypoints=np.asarray(LOOP, dtype=np.float64), speed_m_s=0.5)
    log = simulate(room_world(), path, fine, seed=3, drift=3.0)
    here = tmp_path_factory.mktemp("interleaved")
    turning = write_pioneer_bag(log, here / "turning.bag", interleave=TURNS)
    constant = write_pioneer_bag(log, here / "constant.bag", interleave=TURNS, turning=False)
    return folder, turning, constant


def test_each_scan_is_read_with_its_own_beams(interleaved: tuple[Path, Path, Path]) -> None:
    _, turning, constant = interleaved
    log, same = read_log(turning), read_log(constant)
    assert same.sensor_names == tuple(f"laser_{i}" for i in range(181))
    # every direction of the turn is a beam: the fine laser's 721, each where it points
    assert log.sensors is not None and len(log.sensor_names) == 180 * TURNS + 1
    yaws = np.sort([s.yaw_rad for s in log.sensors])
    fine = np.linspace(-math.pi / 2, math.pi / 2, 180 * TURNS + 1)
    assert np.abs(yaws - fine).max() < 1e-6
    # each scan's beams are its own: scan k of a turn holds beams a quarter step on
    scans = np.unique(log.readings.stamp_ns)
    first_yaw = []
    for stamp in scans[:TURNS]:
        beams = log.readings.sensor[log.readings.stamp_ns == stamp]
        first_yaw.append(min(log.sensors[int(b)].yaw_rad for b in beams))
    step = math.pi / 180
    assert np.diff(first_yaw) == pytest.approx([step / TURNS] * (TURNS - 1), abs=1e-3 * step)


def test_bulk_and_message_by_message_read_an_interleaving_laser_alike(
    interleaved: tuple[Path, Path, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    _, turning, _ = interleaved
    bulk = read_log(turning)
    monkeypatch.setattr(mcap_bulk, "BULK_DECODE", False)
    one_by_one = read_log(turning)
    assert one_by_one.sensor_names == bulk.sensor_names and one_by_one.sensors == bulk.sensors
    assert np.array_equal(one_by_one.readings.sensor, bulk.readings.sensor)
    assert np.array_equal(one_by_one.readings.range_m, bulk.readings.range_m)


@pytest.mark.parametrize("pose", ["odometry", "scan-matched"])
def test_an_interleaving_laser_maps_as_the_same_laser_with_one_geometry(
    interleaved: tuple[Path, Path, Path], pose: str
) -> None:
    folder, turning, constant = interleaved
    scores = [f1(folder, bag, pose) for bag in (turning, constant)]
    assert scores[0] >= scores[1] - 0.02, scores
    if pose == "scan-matched":
        assert scores[0] >= 0.9


def test_error_aware_maps_of_an_interleaving_laser_score_as_one_geometry(
    interleaved: tuple[Path, Path, Path],
) -> None:
    folder, turning, constant = interleaved
    error = ("--mode", "error-aware", "--odometry-coefficient", "range_m_per_m=0.02")
    scores = [f1(folder, bag, "odometry", *error) for bag in (turning, constant)]
    assert scores[0] >= scores[1] - 0.02, scores


def test_a_scan_whose_ranges_do_not_fit_its_angles_is_one_line(
    pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    _, log = pioneer
    bag = write_pioneer_bag(log, tmp_path / "skewed.bag", skewed=3)
    out = tmp_path / "map.png"
    code, _, stderr = run("build", str(bag), "-o", str(out))
    assert code == 1
    (line,) = stderr.strip().splitlines()
    assert re.fullmatch(
        rf"Error: {re.escape(str(bag))}: /scan at log time 1600000000\.30\d+ s: laser 'laser': "
        r"181 ranges, but its angles do not fit them \(from -1\.5708 to 1\.74533 rad by "
        r"0\.0174533: angle_max must be angle_min \+ \(ranges - 1\) x angle_increment\)",
        line,
    ), line
    assert not out.exists() and not out.with_suffix(".yaml").exists()


@pytest.fixture(scope="module")
def laser_alone(pioneer: tuple[Path, RangeLog]) -> Path:
    """The Pioneer bag without its odometry (no /RosAria/pose, no odom -> base_link)."""
    folder, log = pioneer
    return write_pioneer_bag(log, folder / "laser-alone.bag", odometry=False)


def test_a_laser_without_odometry_maps_with_slam(
    pioneer: tuple[Path, RangeLog], laser_alone: Path
) -> None:
    folder, _ = pioneer
    assert f1(folder, laser_alone, "slam") >= 0.60
    out = folder / "alone.png"
    code, stdout, stderr = run("build", str(laser_alone), "--pose", "slam", "-o", str(out),
                               "--force", "--json")  # fmt: skip
    assert code == 0, stderr
    assert json.loads(stdout)["motion"] == "no odometry: motion from the scans"
    code, _, stderr = run("build", str(laser_alone), "--pose", "slam", "-o", str(out), "--force")
    assert code == 0 and "; no odometry: motion from the scans" in stderr


def test_a_laser_without_odometry_gives_a_scan_matched_track(
    pioneer: tuple[Path, RangeLog], laser_alone: Path, tmp_path: Path
) -> None:
    """The track starts at the first scan and follows the true path's shape: the loop's
    corners, seen from the start, where the truth has them."""
    _, log = pioneer
    out = tmp_path / "sm.tum"
    code, _, stderr = run("trajectory", str(laser_alone), "--pose", "scan-matched", "-o", str(out))
    assert code == 0, stderr
    assert "no odometry: motion from the scans" in stderr
    track = np.loadtxt(out)
    truth = log.truth
    assert truth is not None
    t = (track[:, 0] * 1e9).astype(np.int64) - 1_600_000_000 * 1_000_000_000
    tx = np.interp(t, truth.stamp_ns, truth.x_m) - truth.x_m[0]
    ty = np.interp(t, truth.stamp_ns, truth.y_m) - truth.y_m[0]
    c, s = math.cos(-truth.theta_rad[0]), math.sin(-truth.theta_rad[0])
    ex, ey = c * tx - s * ty - track[:, 1], s * tx + c * ty - track[:, 2]
    assert np.hypot(ex, ey).max() < 0.15


def test_odometry_is_still_asked_for_where_the_pose_needs_it(
    laser_alone: Path, tmp_path: Path
) -> None:
    out = tmp_path / "map.png"
    code, _, stderr = run("build", str(laser_alone), "-o", str(out), "--pose", "odometry")
    assert code == 1
    (line,) = stderr.strip().splitlines()
    assert line.startswith(f"Error: {laser_alone}: no odometry: no pose topic and no 'odom'")
    assert not out.exists()
    # the default choice maps it with the pose graph, its motion from the scans
    code, stdout, stderr = run("build", str(laser_alone), "-o", str(out), "--json")
    assert code == 0, stderr
    summary = json.loads(stdout)
    assert summary["pose_choice"]["source"] == "slam"
    assert summary["motion"] == "no odometry: motion from the scans"


def test_inspect_says_a_laser_without_odometry_is_ready_and_how_build_moves_it(
    laser_alone: Path, pioneer: tuple[Path, RangeLog], tmp_path: Path
) -> None:
    """inspect's verdict on a laser alone: ready, the motion from the scans (it raised
    IndexError synchronising with the empty odometry); unmounted, the mounting build stops at."""
    code, stdout, stderr = run("inspect", str(laser_alone), "--json")
    assert code == 0, stderr
    verdict = json.loads(stdout)["build"]
    assert verdict["ready"] and verdict["problem"] is None
    assert verdict["odometry"].startswith("none: no pose topic and no 'odom' -> 'base_link'")
    assert verdict["odometry"].endswith("; build takes the motion from the laser's scans")
    _, log = pioneer
    bare = write_pioneer_bag(log, tmp_path / "bare.bag", odometry=False, mounting=None)
    code, stdout, stderr = run("inspect", str(bare), "--json")
    assert code == 1 and stderr.count("\n") == 1, stderr
    verdict = json.loads(stdout)["build"]
    assert not verdict["ready"]
    assert verdict["problem"].startswith(
        f"{bare}: sensor frame 'laser' (/scan): mounting pose unknown"
    )


def test_batch_maps_a_laser_without_odometry_and_says_so(laser_alone: Path, tmp_path: Path) -> None:
    folder = tmp_path / "logs"
    folder.mkdir()
    (folder / "alone.bag").write_bytes(laser_alone.read_bytes())
    out = tmp_path / "maps"
    code, _, stderr = run("batch", str(folder), "-o", str(out), "--pose", "slam")
    assert code == 0, stderr
    (report,) = [json.loads(line) for line in (out / "batch-report.jsonl").read_text().splitlines()]
    assert report["status"] == "built"
    assert report["warnings"] == ["no odometry: motion from the scans"]


@pytest.fixture(scope="module")
def sparse_alone(pioneer: tuple[Path, RangeLog]) -> Path:
    """The Pioneer bag without its odometry and with one scan in twelve: half a metre or more
    between scans, as a log thinned to a scan per stretch driven keeps them."""
    folder, log = pioneer
    stamps = np.unique(log.readings.stamp_ns)[::12]
    keep = np.isin(log.readings.stamp_ns, stamps)
    r = log.readings
    thinned = dataclasses.replace(
        log,
        readings=dataclasses.replace(
            r, stamp_ns=r.stamp_ns[keep], sensor=r.sensor[keep], range_m=r.range_m[keep]
        ),
    )
    return write_pioneer_bag(thinned, folder / "sparse-alone.bag", odometry=False)


def test_a_laser_without_odometry_warns_where_its_scans_are_far_apart(
    sparse_alone: Path, laser_alone: Path, tmp_path: Path
) -> None:
    out = tmp_path / "map.png"
    for pose in ("slam", "scan-matched", "auto"):
        code, stdout, stderr = run(
            "build", str(sparse_alone), "-o", str(out), "--pose", pose, "--force", "--json"
        )
        assert code == 0, stderr
        summary = json.loads(stdout)
        assert summary["motion"] == "no odometry: motion from the scans"
        (line,) = [w for w in stderr.splitlines() if "m apart" in w]
        found = re.search(r"the scans are ([0-9.]+) m apart", line)
        assert found is not None and float(found.group(1)) > 0.15
        assert f"--pose {pose}: no odometry, and the scans are " in line
        assert line.endswith("check the map")
    # trajectory, which writes the same track, says so too
    code, _, stderr = run("trajectory", str(sparse_alone), "-o", str(tmp_path / "t.csv"))
    assert code == 0, stderr
    assert "Warning: --pose auto: no odometry, and the scans are " in stderr
    # the full-rate bag: its scans a few centimetres apart, nothing to warn of
    code, stdout, stderr = run("build", str(laser_alone), "-o", str(out), "--force", "--json")
    assert code == 0, stderr
    assert json.loads(stdout)["motion"] == "no odometry: motion from the scans"
    assert "m apart" not in stderr


def test_a_laser_without_odometry_falls_back_from_a_failing_graph(
    laser_alone: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The fallback places the scans with the matcher's track, itself carried by the motion
    from the scans (the log has no odometry to carry it)."""
    from gridmap_cli.poses import sources

    monkeypatch.setattr(sources, "graph_failure", lambda result: "forced for the test")
    out = tmp_path / "map.png"
    code, stdout, stderr = run("build", str(laser_alone), "-o", str(out), "--json")
    assert code == 0, stderr
    summary = json.loads(stdout)
    assert summary["pose_choice"]["source"] == "scan-matched"
    assert summary["motion"] == "no odometry: motion from the scans"
    assert "mapped with the scan-matched track instead" in stderr
    assert out.exists()
