"""gridmap trajectory: tracks as TUM (what evo reads) and CSV, for every pose source."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.records import PoseTrack
from gridmap_cli.writers.trajectory import trajectory_text
from tests.helpers import names, run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


def test_tum_is_seconds_position_and_a_yaw_quaternion() -> None:
    track = PoseTrack.from_rows(
        np.array([1_500_000_000, 2_000_000_000], dtype=np.int64),
        [(1.0, 2.0, 0.0), (3.0, -1.0, math.pi / 2)],
    )
    lines = trajectory_text(track, "tum").splitlines()
    assert lines[0] == "1.5 1.0 2.0 0 0 0 0.0 1.0"
    t, x, y, z, qx, qy, qz, qw = (float(v) for v in lines[1].split())
    assert (t, x, y, z, qx, qy) == (2.0, 3.0, -1.0, 0.0, 0.0, 0.0)
    assert 2 * math.atan2(qz, qw) == pytest.approx(math.pi / 2)


def test_csv_has_a_header_and_the_status_when_given() -> None:
    track = PoseTrack.from_rows(np.array([0], dtype=np.int64), [(1.0, 2.0, 0.5)])
    assert trajectory_text(track, "csv") == "time,x,y,theta\n0.0,1.0,2.0,0.5\n"
    assert trajectory_text(track, "csv", ["first"]).endswith("0.5,first\n")


@pytest.mark.parametrize("pose", ["odometry", "global"])
def test_odometry_and_reference_tracks_of_a_sonar_log(tmp_path: Path, pose: str) -> None:
    out = tmp_path / "track.tum"
    log = SAMPLES / "corridor_loop.csv"
    code, stdout, stderr = run("trajectory", str(log), "--pose", pose, "-o", str(out), "--json")
    assert code == 0, stderr
    rows = np.loadtxt(out)
    assert rows.shape[1] == 8 and json.loads(stdout)["poses"] == rows.shape[0] > 100
    assert stderr.startswith(f"gridmap: {rows.shape[0]:,} {pose} poses -> {out}")


def test_scan_matched_needs_a_laser(tmp_path: Path) -> None:
    log = SAMPLES / "corridor_loop.csv"
    out = str(tmp_path / "t.tum")
    code, _, stderr = run("trajectory", str(log), "--pose", "scan-matched", "-o", out)
    assert code == 1 and "has no laser" in stderr and names(tmp_path) == set()


def test_the_default_track_is_the_odometry_as_in_build(tmp_path: Path) -> None:
    """One default across commands: a sonar log's track is written without --pose."""
    out = tmp_path / "t.tum"
    code, stdout, stderr = run("trajectory", str(SAMPLES / "corridor_loop.csv"), "-o", str(out),
                               "--json")  # fmt: skip
    assert code == 0, stderr
    assert json.loads(stdout)["pose"] == "odometry" and " odometry poses -> " in stderr
    assert np.loadtxt(out).shape[0] == json.loads(stdout)["poses"]


TURTLEBOT = SAMPLES.parent.parent / "shared" / "data" / "mcap" / "rosbag2_turtlebot_odometry.mcap"


@pytest.mark.skipif(not TURTLEBOT.is_file(), reason="../shared/data is not present")
@pytest.mark.parametrize(
    ("pose", "flags", "source"),
    [
        ("odometry", (), "/odom"),
        ("global", (), "TF map -> odom"),
        ("global", ("--pose-topic", "/amcl_pose"), "/amcl_pose"),
    ],
)
def test_a_recording_without_range_readings_gives_its_tracks(
    tmp_path: Path, pose: str, flags: tuple[str, ...], source: str
) -> None:
    """The TurtleBot rosbag2 holds /odom, TF map -> odom and /amcl_pose and no range topic: its
    odometry, its TF reference and its AMCL track are each written (a TUM export for evo)."""
    out = tmp_path / "t.tum"
    code, stdout, stderr = run("trajectory", str(TURTLEBOT), "--pose", pose, *flags,
                               "-o", str(out), "--json")  # fmt: skip
    assert code == 0, f"{source}: {stderr}"
    rows = np.loadtxt(out)
    assert rows.shape == (json.loads(stdout)["poses"], 8)
    # the AMCL pose comes at about 1.4 Hz, odometry and TF at 27 Hz
    assert (rows.shape[0] < 200) == (source == "/amcl_pose") and rows.shape[0] > 100
    assert np.all(np.diff(rows[:, 0]) > 0)


@pytest.mark.skipif(not TURTLEBOT.is_file(), reason="../shared/data is not present")
def test_a_laser_track_of_a_recording_without_range_readings_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "t.tum"
    code, _, stderr = run("trajectory", str(TURTLEBOT), "--pose", "scan-matched", "-o", str(out))
    lines = stderr.strip().splitlines()
    assert code == 1 and len(lines) == 1 and "no range readings" in lines[0]
    assert names(tmp_path) == set()


def test_usage_errors_write_nothing(tmp_path: Path) -> None:
    log = SAMPLES / "corridor_loop.csv"
    code, _, stderr = run("trajectory", str(log), "-o", str(tmp_path / "t.json"))
    assert code == 2 and "written as .tum (TUM, what evo reads) or .csv" in stderr
    (tmp_path / "t.csv").write_text("keep")
    code, _, stderr = run(
        "trajectory", str(log), "--pose", "odometry", "-o", str(tmp_path / "t.csv")
    )
    assert code != 0 and (tmp_path / "t.csv").read_text() == "keep"
