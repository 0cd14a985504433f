"""gridmap build --pose scan-matched as a user meets it: a laser log of any format, the
fallback count in the summary, the error for a log without a laser, the real CARMEN logs."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.poses.correction.scan_match import match_log
from gridmap_cli.readers import read_logs
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.writers.csv_log import save_csv_log
from tests.helpers import names, run
from tests.readers.test_carmen_real import DATA
from tests.test_scan_match import errors, room_world
from tests.test_scan_match import run as simulate_run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


def test_log_without_laser_is_one_error_line_and_nothing_written(tmp_path: Path) -> None:
    out = tmp_path / "map.png"
    log = SAMPLES / "corridor_loop.csv"
    code, stdout, stderr = run("build", str(log), "-o", str(out), "--pose", "scan-matched")
    assert code == 1 and stdout == ""
    assert stderr == (
        f"Error: {log}: --pose scan-matched matches laser scans, and the log has no laser "
        "(its range sensors: sonar); use --pose odometry or global\n"
    )
    assert names(tmp_path) == set()


@pytest.mark.parametrize("suffix", [".csv", ".2d", ".mcap"])
def test_laser_log_of_every_format_is_matched(tmp_path: Path, suffix: str) -> None:
    log = simulate_run(room_world(), [[2, 1.5], [10, 1.5], [10, 6.5]], drift=3.0)
    log.metadata["robot"] = "p3at-lms200"
    csv = tmp_path / "run.csv"
    save_csv_log(log, csv)
    source = csv
    if suffix != ".csv":
        source = tmp_path / f"run{suffix}"
        code, _, err = run("convert", str(csv), str(source), "-q")
        assert code == 0, err
    out = tmp_path / "map.png"
    code, stdout, stderr = run(
        "build", str(source), "-o", str(out), "--pose", "scan-matched", "--json",
        "--robot", "p3at-lms200",
    )  # fmt: skip
    assert code == 0, stderr
    summary = json.loads(stdout)["scan_match"]
    assert summary["scans"] > 100 and summary["fallbacks"] == 0
    assert "fell back to odometry" in stderr
    assert out.is_file()


@pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/carmen is not present")
def test_aces_track_is_much_closer_to_the_corrected_poses_than_odometry() -> None:
    """Translation error after aligning each track's first pose with the reference's."""
    log = read_logs((DATA / "aces-corrected.log.gz",), None, ReadOptions())
    match = match_log(log, None)
    ex, ey, eth = errors(log, match.track)
    ox, oy, _ = errors(log, match.odometry)
    sm, odo = float(np.sqrt(np.mean(ex**2 + ey**2))), float(np.sqrt(np.mean(ox**2 + oy**2)))
    assert sm < 0.5 * odo
    assert float(np.sqrt(np.mean(eth**2))) < math.radians(5.0)
    assert match.fallbacks < 0.05 * len(match.track)


def test_calibrate_scan_matched_finds_less_drift_than_odometry(tmp_path: Path) -> None:
    """The residual drift of the corrected track, against the same reference."""
    log = simulate_run(room_world(), [[2, 1.5], [10, 1.5], [10, 6.5], [2, 6.5]], drift=3.0)
    log.metadata["robot"] = "p3at-lms200"
    csv = tmp_path / "run.csv"
    save_csv_log(log, csv)
    figures = {}
    for pose in ("odometry", "scan-matched", "slam"):
        out = tmp_path / f"{pose}.yaml"
        code, stdout, stderr = run(
            "calibrate", str(csv), "--pose", pose, "-o", str(out), "--json", "--window", "0.5"
        )
        assert code == 0, stderr
        figures[pose] = json.loads(stdout)
        assert out.is_file()
    assert "--pose scan-matched" in (tmp_path / "scan-matched.yaml").read_text()
    odo, sm = figures["odometry"]["coefficients"], figures["scan-matched"]["coefficients"]
    assert sm["heading_drift_rad_per_m"] < 0.5 * odo["heading_drift_rad_per_m"]
    assert sm["range_m_per_m"] < odo["range_m_per_m"]
    # the pose graph's track (loop closures on top of the matching) drifts less than odometry
    assert "--pose slam" in (tmp_path / "slam.yaml").read_text()
    slam = figures["slam"]["coefficients"]
    assert slam["heading_drift_rad_per_m"] < 0.5 * odo["heading_drift_rad_per_m"]
    assert slam["range_m_per_m"] < odo["range_m_per_m"]


@pytest.mark.parametrize("pose", ["scan-matched", "slam"])
def test_calibrate_a_corrected_track_against_a_correction_of_itself_is_refused(
    tmp_path: Path, pose: str
) -> None:
    csv = tmp_path / "run.csv"
    csv.write_text("time,x,y,theta,sonar0\n0,0,0,0,1\n")
    out = tmp_path / "odometry.yaml"
    code, _, err = run("calibrate", str(csv), "--pose", pose, "--reference", "slam", "-o", str(out))
    assert code == 2 and err.count("\n") == 1, err
    assert f"--pose {pose} --reference slam: the corrected track would be compared" in err
    assert not out.exists()
