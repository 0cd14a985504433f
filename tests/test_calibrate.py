"""calibrate: logs whose odometry error is known exactly, a simulated one, and bad input."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.errors import InputFileError
from gridmap_cli.mapping.mapfile import load_map
from gridmap_cli.poses.calibration.calibrate import CalibrationError, calibrate
from gridmap_cli.poses.odometry_error import (
    VERSION_2_KEYS,
    VERSION_3_KEYS,
    OdometryError,
    load_odometry_error,
)
from gridmap_cli.readers import read_log
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import load_robot
from gridmap_cli.sim.odometry import OdometryErrorModel
from gridmap_cli.sim.path import load_path
from gridmap_cli.sim.simulate import simulate
from gridmap_cli.sim.world import World
from gridmap_cli.writers.aria_log import save_aria_log
from gridmap_cli.writers.csv_log import save_csv_log
from tests.helpers import log_with_truth, names, run
from tests.readers.test_carmen_real import DATA as CARMEN

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
SONAR0 = load_robot("p3dx").sensors[:1]


def straight_line(scale: float, metres: float = 10.0) -> RangeLog:
    """Driving 4 cm per step along the world's y axis from (3, 1); odometry scaled by 1 + scale.

    The truth starts at heading 90 deg, the odometry at 0: each window is compared in its own
    start frame, so the two frames need not agree.
    """
    steps = round(metres / 0.04)
    truth = [(3.0, 1.0 + 0.04 * k, math.pi / 2) for k in range(steps + 1)]
    odometry = [(0.04 * k * (1.0 + scale), 0.0, 0.0) for k in range(steps + 1)]
    return log_with_truth(truth, odometry)


def spin_in_place(turn_scale: float, turns: float = 3.1) -> RangeLog:
    """Turning on the spot 3 degrees per step; the odometry reports (1 + turn_scale) of each."""
    steps = round(turns * 120)
    step = math.radians(3.0)
    truth = [(1.0, 2.0, math.remainder(k * step, math.tau)) for k in range(steps + 1)]
    reported = step * (1.0 + turn_scale)
    odo = [(0.0, 0.0, math.remainder(k * reported, math.tau)) for k in range(steps + 1)]
    return log_with_truth(truth, odo)


def test_straight_line_with_a_two_percent_scale_error() -> None:
    # every 1 m window: odometry says 1.02 m, so e_d = 0.02 * 1 m exactly; no rotation at all
    c = calibrate(straight_line(0.02))
    assert c.windows == 10 and c.driving_windows == 10
    assert c.scale_error == pytest.approx(0.02, abs=1e-9)
    assert c.model.range_m_per_m == pytest.approx(0.02, abs=1e-9)
    assert c.model.range_m_per_sqrt_m == pytest.approx(0.0, abs=1e-7)
    assert c.model.heading_drift_rad_per_m == 0.0 and c.drift_estimated
    assert c.model.bearing_rad_per_rad == 0.0 and c.model.bearing_rad_per_sqrt_rad == 0.0
    assert not c.turn_estimated  # nothing turned: the turn terms cannot be known


def test_under_reporting_odometry_gives_the_same_spread() -> None:
    c = calibrate(straight_line(-0.03))
    assert c.scale_error == pytest.approx(-0.03, abs=1e-9)
    assert c.model.range_m_per_m == pytest.approx(0.03, abs=1e-9)


def test_spin_in_place_with_a_three_percent_turn_scale_error() -> None:
    # 3.1 turns = 12 complete windows of 90 deg; each reports 92.7 deg: e_h = 0.03 * pi / 2
    c = calibrate(spin_in_place(0.03))
    assert c.windows == 12 and c.turning_windows == 12
    assert c.turn_scale_error == pytest.approx(0.03, abs=1e-9)
    assert c.model.bearing_rad_per_rad == pytest.approx(0.03, abs=1e-9)
    assert c.model.bearing_rad_per_sqrt_rad == pytest.approx(0.0, abs=1e-7)
    assert not c.distance_estimated and c.model.range_m_per_m == 0.0


def test_heading_drift_per_metre() -> None:
    # a straight line in truth, an arc in odometry: heading grows 0.004 rad per metre
    steps = 250
    truth = [(0.04 * k, 0.0, 0.0) for k in range(steps + 1)]
    odo = [(0.04 * k, 0.0, 0.004 * 0.04 * k) for k in range(steps + 1)]
    c = calibrate(log_with_truth(truth, odo))
    assert c.heading_drift_rad_per_m == pytest.approx(0.004, abs=1e-9)


def test_the_same_log_as_csv_and_aria(tmp_path: Path) -> None:
    log = straight_line(0.02)
    save_csv_log(log, tmp_path / "line.csv")
    save_aria_log(log, SONAR0, tmp_path / "line.2d")
    from_csv = calibrate(read_log(tmp_path / "line.csv"))
    from_aria = calibrate(read_log(tmp_path / "line.2d"))
    assert from_csv.model.range_m_per_m == pytest.approx(0.02, abs=1e-9)
    # ARIA stores poses in whole millimetres: the 1.02 m windows come back to within 1 mm
    assert from_aria.model.range_m_per_m == pytest.approx(0.02, abs=1e-3)
    assert from_aria.windows == from_csv.windows


def test_a_simulated_drift_1_log_finds_the_simulators_errors() -> None:
    # samples/corridor_loop.csv is `gridmap simulate --drift 1` (tests/test_samples.py checks
    # that); one 56 m lap with 3 corners. Found: scale 0.00802, distance walk 0.00993, turn scale
    # 0.01251, turn walk 0.01171, drift 0.00313 rad/m against the simulator's 0.01, 0.01, 0.02,
    # 0.02, 0.00349. Three corners say little about turning, so allow a factor of two; the
    # turn scale they give (0.012) is within 2 standard errors of 0, so it is not written
    # (poses/calibration/bias_check.py): a bias the log cannot tell from noise is not known.
    c = calibrate(read_log(SAMPLES / "corridor_loop.csv"))
    sim = OdometryErrorModel().as_odometry_error()
    checks = {b.key: b for b in c.bias_checks}
    assert not checks["turn_scale_bias"].applied
    assert checks["turn_scale_bias"].reason == "within noise of 0"
    assert c.model.turn_scale_bias == c.model.bearing_rad_per_rad == 0.0
    assert 0.5 * OdometryErrorModel().turn_scale_error < c.turn_scale_error  # measured, printed
    for name, true in sim.as_dict().items():
        found = getattr(c.model, name)
        if name == "bearing_rad_per_rad":
            continue  # not written: above
        if name == "sonar_relative_error":
            assert found == true  # not calibrated: the default is passed through
        elif name in VERSION_2_KEYS:
            assert found == true == 0.0  # version-2 terms: neither simulated nor calibrated
        elif name in VERSION_3_KEYS:
            continue  # signed: below
        else:
            assert true / 2 < found < true * 2, (name, found, true)
    assert c.heading_drift_rad_per_m == pytest.approx(sim.heading_drift_rad_per_m, rel=0.15)
    # version 3: the signs too, what --correct-odometry takes out
    signed = OdometryErrorModel()
    assert 0.5 * signed.scale_error < c.model.distance_scale_bias < 2 * signed.scale_error
    assert checks["distance_scale_bias"].applied and checks["heading_drift_bias_rad_per_m"].applied
    assert c.model.heading_drift_bias_rad_per_m == pytest.approx(
        signed.heading_drift_rad_per_m, rel=0.15
    )


def test_log_without_truth_is_refused(tmp_path: Path) -> None:
    log = straight_line(0.02)
    no_truth = RangeLog(log.source, log.poses, log.readings, log.sensor_names, metadata={})
    with pytest.raises(InputFileError, match="the log has no ground truth"):
        calibrate(no_truth)
    save_csv_log(no_truth, tmp_path / "plain.csv")
    out = tmp_path / "odo.yaml"
    code, _, err = run("calibrate", str(tmp_path / "plain.csv"), "-o", str(out))
    assert code == 1
    assert err == (
        f"Error: {tmp_path / 'plain.csv'}: the log has neither a reference track (ground truth, "
        "a SLAM track) nor a laser to make one (--reference scan-matched): nothing to calibrate "
        "the odometry against\n"
    )
    assert names(tmp_path) == {"plain.csv"}


def test_too_little_travel(tmp_path: Path) -> None:
    save_csv_log(straight_line(0.02, metres=2.6), tmp_path / "short.csv")
    code, _, err = run("calibrate", str(tmp_path / "short.csv"), "-o", str(tmp_path / "o.yaml"))
    assert code == 1
    assert "too little travel to calibrate: the truth drives 2.60 m and turns 0 deg" in err
    assert "2 complete windows of 1 m or 90 deg; need at least 3" in err
    assert names(tmp_path) == {"short.csv"}


def test_cli_writes_the_yaml_build_takes(tmp_path: Path) -> None:
    save_csv_log(straight_line(0.02), tmp_path / "line.csv")
    out = tmp_path / "odo.yaml"
    code, stdout, _ = run("calibrate", str(tmp_path / "line.csv"), "-o", str(out))
    assert code == 0, stdout
    assert "distance scale error   +2.00 % of distance" in stdout
    assert "turn scale error       not estimated" in stdout
    model = load_odometry_error(out)
    assert model.range_m_per_m == pytest.approx(0.02, abs=1e-9)
    assert model.sonar_relative_error == 0.01
    assert out.read_text().startswith("# gridmap ")
    code, _, err = run("calibrate", str(tmp_path / "line.csv"), "-o", str(out))
    assert code == 1 and "exists (use --force to overwrite)" in err
    code, stdout, _ = run(
        "calibrate", str(tmp_path / "line.csv"), "--json", "--window", "2", "--sonar-error", "0"
    )
    doc = json.loads(stdout)
    assert doc["windows"]["total"] == 5 and doc["output"] is None
    assert doc["coefficients"]["sonar_relative_error"] == 0.0
    assert doc["signed"]["scale_error"] == pytest.approx(0.02, abs=1e-9)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--window", "0"], "--window must be a positive number of metres, got 0.0"),
        (["--window-turn", "nan"], "--window-turn must be a positive number of degrees"),
        (["--sonar-error", "-1"], "--sonar-error must be a finite number >= 0"),
    ],
)
def test_bad_options_are_usage_errors(tmp_path: Path, args: list[str], message: str) -> None:
    save_csv_log(straight_line(0.02), tmp_path / "line.csv")
    code, _, err = run("calibrate", str(tmp_path / "line.csv"), *args)
    assert code == 2 and message in err


def test_missing_log(tmp_path: Path) -> None:
    code, _, err = run("calibrate", str(tmp_path / "absent.csv"))
    assert code == 1 and err == f"Error: {tmp_path / 'absent.csv'}: no such file\n"


def test_perfect_odometry_calibrates_to_exact_zeros(tmp_path: Path) -> None:
    # rounding noise (1e-17) is written as 0, so the file says "no error" in so many words
    line = straight_line(0.0)
    save_csv_log(line, tmp_path / "line.csv")
    assert calibrate(read_log(tmp_path / "line.csv")).model == OdometryError()
    assert calibrate(spin_in_place(0.0)).model == OdometryError()


def test_same_run_from_csv_and_ros2_mcap_calibrates_the_same() -> None:
    """Quaternions round headings by an ulp; window budgets must not depend on that."""
    samples = Path(__file__).resolve().parents[1] / "samples"
    csv = calibrate(read_log(samples / "corridor_loop.csv")).model.as_dict()
    ros2 = calibrate(read_log(samples / "corridor_loop_ros2.mcap")).model.as_dict()
    assert ros2 == pytest.approx(csv, rel=1e-6, abs=1e-12)


def test_truth_that_never_overlaps_the_odometry_drives_nothing() -> None:
    log = straight_line(0.02)
    later = PoseTrack(
        log.poses.stamp_ns + 10**12, log.poses.x_m, log.poses.y_m, log.poses.theta_rad
    )
    apart = RangeLog(log.source, log.poses, log.readings, log.sensor_names, truth=later)
    with pytest.raises(CalibrationError) as caught:
        calibrate(apart)
    assert "the truth drives 0.00 m and turns 0 deg, 0 complete windows" in str(caught.value)


def test_a_missing_log_is_reported_before_an_existing_output(tmp_path: Path) -> None:
    existing = tmp_path / "odometry.yaml"
    existing.write_text("keep\n")
    code, _, err = run("calibrate", str(tmp_path / "missing.csv"), "-o", str(existing))
    assert (code, err.strip()) == (1, f"Error: {tmp_path / 'missing.csv'}: no such file")
    assert existing.read_text() == "keep\n"


def test_jitter_of_a_reference_is_taken_out_of_the_random_walk() -> None:
    # the simulated lap's truth with 5 cm and 1 deg of independent noise on every pose: what a
    # SLAM track adds. Without the jitter ladder the random walks would take it all in; with
    # it, the jitter comes out near 5 cm and 1 deg and the random walk near the clean log's
    clean = read_log(SAMPLES / "corridor_loop.csv")
    assert clean.truth is not None
    rng = np.random.default_rng(7)
    t = clean.truth
    noisy = PoseTrack(
        t.stamp_ns,
        t.x_m + rng.normal(0.0, 0.05, len(t)),
        t.y_m + rng.normal(0.0, 0.05, len(t)),
        t.theta_rad + rng.normal(0.0, math.radians(1.0), len(t)),
    )
    c0 = calibrate(clean)
    c = calibrate(dataclasses.replace(clean, truth=noisy))
    assert c.jitter_estimated
    assert 0.035 < c.jitter_m < 0.065, c.jitter_m
    assert 0.6 < math.degrees(c.jitter_rad) < 1.4, math.degrees(c.jitter_rad)
    assert c.model.range_m_per_sqrt_m < 2.5 * c0.model.range_m_per_sqrt_m + 0.01
    assert c.halves is not None and len(c.halves) == 2


@pytest.mark.skipif(not CARMEN.is_dir(), reason="../shared/data/carmen is not present")
def test_a_real_slam_reference_reports_its_jitter_and_the_halves() -> None:
    # ACES: the corrected (SLAM) track jitters by about 8 cm and 4.6 deg per pose; without the
    # ladder all of it went into the random walks. The halves agree on the distance scale
    # within a factor of 1.5 (0.0181 and 0.0127)
    log = CARMEN / "aces-corrected.log.gz"
    c = calibrate(read_log(log))
    assert c.jitter_estimated
    assert 0.04 < c.jitter_m < 0.15
    assert 2.0 < math.degrees(c.jitter_rad) < 8.0
    assert c.model.range_m_per_sqrt_m < 0.05
    assert c.halves is not None
    scales = [h.range_m_per_m for h in c.halves]
    assert max(scales) < 1.5 * min(scales)
    code, out, _ = run("calibrate", str(log), "--json")
    assert code == 0
    doc = json.loads(out)
    assert doc["reference_jitter"]["estimated"] is True
    assert len(doc["halves"]) == 2
    code, table, _ = run("calibrate", str(log))
    assert "reference jitter" in table and "each half of the span" in table
    assert "left out" in table and doc["robust"]["left_out"]


def test_jumps_of_the_reference_are_left_out_not_fitted() -> None:
    # a SLAM reference snaps at loop closures: ten minutes of the simulated loop (four laps,
    # 220 m) whose truth jumps by 40 cm and 8 deg twice. A least-squares fit of the squared
    # residuals takes each jump squared into the random walks; the robust fit leaves the
    # windows that hold one out and says where
    loaded = load_map(SAMPLES / "worlds" / "corridor_loop.yaml")
    clean = simulate(
        World(loaded.occupied_mask(), loaded.spec),
        load_path(SAMPLES / "paths" / "corridor_loop.yaml"),
        load_robot("p3at"),
        seed=3,
        duration_s=600.0,
    )
    t = clean.truth
    assert t is not None
    jumps = (2000, 4000)
    shift = np.zeros(len(t))
    for j in jumps:
        shift[j:] += 1.0
    snapped = PoseTrack(
        t.stamp_ns, t.x_m + 0.4 * shift, t.y_m - 0.2 * shift, t.theta_rad + math.radians(8) * shift
    )
    c0 = calibrate(clean)
    c = calibrate(dataclasses.replace(clean, truth=snapped))
    m, m0 = c.model, c0.model
    assert m.range_m_per_sqrt_m < 1.5 * m0.range_m_per_sqrt_m + 0.005
    assert m.bearing_rad_per_sqrt_rad < 1.5 * m0.bearing_rad_per_sqrt_rad + 0.005
    assert m.heading_rad_per_sqrt_m < 0.01
    assert m.distance_scale_bias == pytest.approx(m0.distance_scale_bias, abs=0.003)
    assert m.heading_drift_bias_rad_per_m == pytest.approx(m0.heading_drift_bias_rad_per_m, rel=0.2)
    # every jump's 1 m window is among those left out
    jump_s = [(int(t.stamp_ns[j]) - int(t.stamp_ns[0])) / 1e9 for j in jumps]
    starts = [w.start_s for w in c.left_out if w.window_m == 1.0]
    for s in jump_s:
        assert any(0.0 <= s - w < 5.0 for w in starts), (s, starts)


def test_the_cli_table_names_the_fit_it_reports() -> None:
    # cli/calibrate.py keeps copies of these so that --help need not import scipy
    from gridmap_cli.cli import calibrate as cli_calibrate
    from gridmap_cli.poses.calibration import calibrate as poses_calibrate
    from gridmap_cli.poses.calibration import robust_fit

    assert cli_calibrate.JITTER_LADDER == poses_calibrate.JITTER_LADDER
    assert cli_calibrate.OUTLIER_SIGMA == robust_fit.OUTLIER_SIGMA
