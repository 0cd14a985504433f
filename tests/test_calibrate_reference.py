"""calibrate --reference scan-matched / slam: a laser log without ground truth calibrates
against gridmap's own corrected poses."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from gridmap_cli.records import RangeLog
from gridmap_cli.writers.csv_log import save_csv_log
from tests.helpers import names, run
from tests.test_scan_match import room_world
from tests.test_scan_match import run as simulate_run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
CORNERS = [[2, 1.5], [10, 1.5], [10, 6.5], [2, 6.5], [2, 1.5], [10, 1.5]]


@pytest.fixture(scope="module")
def laser_log() -> RangeLog:
    log = simulate_run(room_world(), CORNERS, drift=3.0)
    log.metadata["robot"] = "p3at-lms200"
    return log


def calibrated(tmp_path: Path, csv: Path, *args: str) -> dict[str, float]:
    out = tmp_path / "odo.yaml"
    code, stdout, stderr = run("calibrate", str(csv), "-o", str(out), "--json", "--force", *args)
    assert code == 0, stderr
    assert out.is_file()
    coefficients: dict[str, float] = json.loads(stdout)["coefficients"]
    return coefficients


def test_a_laser_log_without_truth_calibrates_against_its_scan_matched_track(
    tmp_path: Path, laser_log: RangeLog
) -> None:
    with_truth = tmp_path / "truth.csv"
    save_csv_log(laser_log, with_truth)
    truth = calibrated(tmp_path, with_truth)
    bare = tmp_path / "bare.csv"
    save_csv_log(dataclasses.replace(laser_log, truth=None), bare)
    code, _, err = run("calibrate", str(bare))
    assert code == 1 and "--reference scan-matched or slam calibrates against" in err
    own = calibrated(tmp_path, bare, "--reference", "scan-matched")
    assert "--reference scan-matched" in (tmp_path / "odo.yaml").read_text()
    # the systematic errors of drift 3 (3 % scale, 0.6 deg/m) are found against either
    for key, tolerance in (("distance_scale_bias", 0.01), ("heading_drift_bias_rad_per_m", 0.004)):
        assert own[key] == pytest.approx(truth[key], abs=tolerance), key
    assert truth["heading_drift_bias_rad_per_m"] > 0.005


def test_the_pose_graph_reference_runs_too(tmp_path: Path, laser_log: RangeLog) -> None:
    pytest.importorskip("gtsam")
    bare = tmp_path / "bare.csv"
    save_csv_log(dataclasses.replace(laser_log, truth=None), bare)
    own = calibrated(tmp_path, bare, "--reference", "slam")
    assert own["heading_drift_bias_rad_per_m"] > 0.005


def test_neither_reference_nor_laser_is_one_error_line(tmp_path: Path) -> None:
    log = SAMPLES / "corridor_loop.csv"
    out = tmp_path / "odo.yaml"
    code, stdout, err = run("calibrate", str(log), "--reference", "scan-matched", "-o", str(out))
    assert code == 1 and stdout == ""
    assert err == (
        f"Error: {log}: --reference scan-matched corrects the odometry with laser scans, and the "
        "log has none (its range sensors: sonar); calibrate needs a reference track or a laser\n"
    )
    assert names(tmp_path) == set()


def test_a_scan_matched_track_against_itself_is_a_usage_error(tmp_path: Path) -> None:
    code, _, err = run(
        "calibrate", str(SAMPLES / "corridor_loop.csv"), "--pose", "scan-matched",
        "--reference", "slam",
    )  # fmt: skip
    assert code == 2 and err.startswith("Error: --pose scan-matched --reference slam:")
    assert len(err.splitlines()) == 1


def test_a_reference_the_pose_graph_warns_of_is_warned_of(
    tmp_path: Path, laser_log: RangeLog, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A calibration is only as good as its reference: the graph's warnings reach the user."""
    pytest.importorskip("gtsam")
    from gridmap_cli.poses.correction import slam

    monkeypatch.setattr(slam, "BEND_WARN_SIGMA", -1.0)  # every closure now "bends" the track
    bare = tmp_path / "bare.csv"
    save_csv_log(dataclasses.replace(laser_log, truth=None), bare)
    out = tmp_path / "odo.yaml"
    code, _, stderr = run("calibrate", str(bare), "--reference", "slam", "-o", str(out))
    assert code == 0, stderr
    assert "Warning: --pose slam: the loop closures bend the scan-matched track" in stderr
    code, _, stderr = run("calibrate", str(bare), "--reference", "slam", "-o", str(out),
                          "--force", "--quiet")  # fmt: skip
    assert code == 0 and "Warning" not in stderr
