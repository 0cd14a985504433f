"""Only the biases that hold across their own log are written, and a laser log checks the file
it is mapped with (poses/calibration/bias_check.py, log_check.py)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest

from gridmap_cli.poses.calibration.bias_check import (
    APPLIED,
    DISAGREE,
    NONE,
    NOT_SHOWN,
    UNCHECKED,
    check_bias,
)
from gridmap_cli.poses.calibration.calibrate import calibrate
from gridmap_cli.poses.calibration.log_check import FileCheck, biases_on_revisits, check_file
from gridmap_cli.poses.calibration.revisit_check import (
    RevisitFactor,
    likelihood_ratio,
    revisit_factor,
)
from gridmap_cli.poses.correction.loop_closure import Closure
from gridmap_cli.poses.odometry_error import OdometryError, correct_track, save_odometry_error
from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise
from gridmap_cli.readers import read_log
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import load_robot
from gridmap_cli.sim.odometry import OdometryErrorModel, odometry_from_truth
from gridmap_cli.sim.path import WaypointPath, trajectory
from gridmap_cli.writers.csv_log import save_csv_log
from tests.helpers import log_with_truth, run
from tests.test_scan_match import room_world
from tests.test_scan_match import run as simulate_run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
DRIFT = "heading_drift_bias_rad_per_m"


@pytest.mark.parametrize(
    ("whole", "se", "halves", "halves_se", "reason"),
    [
        (0.02, 0.001, (0.019, 0.021), (0.002, 0.002), APPLIED),
        # the halves differ by 4 of their own standard errors, yet the whole is larger than
        # their difference: the bias varies a little and is still known
        (0.02, 0.001, (0.01, 0.03), (0.0025, 0.0025), APPLIED),
        # the halves differ by more than the whole: half their difference is its worth
        (0.02, 0.001, (0.005, 0.035), (0.002, 0.002), DISAGREE),
        # they agree, but the whole is 1 of its standard errors from 0
        (0.002, 0.002, (0.001, 0.003), (0.003, 0.003), NOT_SHOWN),
        (0.02, 0.001, None, None, UNCHECKED),
        (0.0, 0.001, (0.0, 0.0), (0.001, 0.001), NONE),
    ],
)
def test_the_verdicts(
    whole: float,
    se: float,
    halves: tuple[float, float] | None,
    halves_se: tuple[float, float] | None,
    reason: str,
) -> None:
    check = check_bias(DRIFT, whole, se, halves, halves_se)
    assert check.reason == reason
    assert check.applied == (reason == APPLIED)


def test_the_threshold_is_two_standard_errors_from_zero() -> None:
    # the jackknife's standard error decides (0.001), then half the halves' difference (0.01)
    assert check_bias(DRIFT, 0.0021, 0.001, (0.002, 0.0022), (0.001, 0.001)).applied
    assert not check_bias(DRIFT, 0.0019, 0.001, (0.0018, 0.002), (0.001, 0.001)).applied
    assert check_bias(DRIFT, 0.021, 0.001, (0.011, 0.031), (0.001, 0.001)).applied
    late = check_bias(DRIFT, 0.019, 0.001, (0.009, 0.029), (0.001, 0.001))
    assert late.reason == DISAGREE and late.disagreement == pytest.approx(0.02 / math.sqrt(2e-6))


def drifting_line(first: float, second: float, metres: float = 40.0) -> RangeLog:
    """A straight line in truth; the odometry's heading grows ``first`` rad per metre over the
    first half of the metres and ``second`` over the second, with a little noise."""
    steps = round(metres / 0.04)
    truth = [(0.04 * k, 0.0, 0.0) for k in range(steps + 1)]
    heading, odo = 0.0, []
    for k in range(steps + 1):
        odo.append((0.04 * k, 0.0, heading + 1e-4 * math.sin(7.3 * k)))
        heading += 0.04 * (first if k < steps // 2 else second)
    return log_with_truth(truth, odo)


def test_a_drift_the_halves_agree_on_is_written() -> None:
    c = calibrate(drifting_line(0.004, 0.004))
    check = {b.key: b for b in c.bias_checks}[DRIFT]
    assert check.applied and check.reason == APPLIED
    assert c.model.heading_drift_bias_rad_per_m == pytest.approx(0.004, abs=1e-4)


def test_a_drift_that_changes_within_the_log_is_not_written(tmp_path: Path) -> None:
    c = calibrate(drifting_line(0.007, 0.001))
    check = {b.key: b for b in c.bias_checks}[DRIFT]
    assert check.reason == DISAGREE and check.halves is not None
    assert check.halves[0] == pytest.approx(0.007, abs=3e-4)
    assert check.halves[1] == pytest.approx(0.001, abs=3e-4)
    # measured and printed, but neither corrected nor spread by build
    assert c.heading_drift_rad_per_m == pytest.approx(0.004, abs=5e-4)
    assert c.model.heading_drift_bias_rad_per_m == 0.0 and c.model.heading_drift_rad_per_m == 0.0
    csv = tmp_path / "line.csv"
    save_csv_log(drifting_line(0.007, 0.001), csv)
    code, stdout, stderr = run("calibrate", str(csv), "--json")
    assert code == 0, stderr
    got = json.loads(stdout)["bias_check"][DRIFT]
    assert got["applied"] is False and got["reason"] == DISAGREE
    code, stdout, _ = run("calibrate", str(csv))
    assert code == 0 and "heading drift: halves disagree, not written" in stdout


@pytest.fixture(scope="module")
def laser_log() -> RangeLog:
    # perfect odometry, two laps of the room (the check on the positions needs starts 20 m
    # and more before the end)
    lap = [[2, 1.5], [10, 1.5], [10, 6.5], [2, 6.5]]
    log = simulate_run(room_world(), [*lap, *lap, [2, 2]], 0.0)
    log.metadata["robot"] = "p3at-lms200"
    return log


def test_a_laser_log_drops_a_bias_it_does_not_show_and_narrows_walks(laser_log: RangeLog) -> None:
    wrong = OdometryError(
        range_m_per_sqrt_m=0.05,
        bearing_rad_per_sqrt_rad=0.05,
        heading_rad_per_sqrt_m=0.02,
        heading_drift_rad_per_m=0.01,
        heading_drift_bias_rad_per_m=0.01,
    )
    check = check_file(laser_log, load_robot("p3at-lms200"), wrong)
    assert check.checked
    assert [d[0] for d in check.dropped] == [DRIFT]
    assert check.model.heading_drift_bias_rad_per_m == 0.0
    # the odometry is perfect: the walks come down to (near) what the laser shows, nothing
    for walk in ("range_m_per_sqrt_m", "bearing_rad_per_sqrt_rad", "heading_rad_per_sqrt_m"):
        assert getattr(check.model, walk) < 0.1 * getattr(wrong, walk), walk
    assert "heading_drift_bias not corrected" in check.summary()
    assert "narrowed to this log's own" in check.summary()
    # two laps of the room: the closure search finds the places seen twice
    assert check.revisits >= 8
    assert f"the log's {check.revisits} revisits show the odometry within" in check.summary()


def test_the_build_says_what_it_did_with_the_file(tmp_path: Path, laser_log: RangeLog) -> None:
    csv = tmp_path / "laser.csv"
    save_csv_log(dataclasses.replace(laser_log, truth=None), csv)
    odo = tmp_path / "odo.yaml"
    save_odometry_error(OdometryError(heading_drift_rad_per_m=0.01,
                                      heading_drift_bias_rad_per_m=0.01), odo)  # fmt: skip
    args = ["build", str(csv), "-o", str(tmp_path / "m.png"), "--robot", "p3at-lms200",
            "--mode", "error-aware", "--odometry-error", str(odo), "--json"]  # fmt: skip
    code, stdout, stderr = run(*args)
    assert code == 0, stderr
    summary = json.loads(stdout)
    assert summary["odometry_check"]["checked"] is True
    assert DRIFT in summary["odometry_check"]["biases_dropped"]
    # standard mode stays drift-blind: no check
    code, stdout, stderr = run(*args[:4], "--robot", "p3at-lms200", "--json", "--force")
    assert code == 0, stderr
    assert "odometry_check" not in json.loads(stdout)


def test_a_sonar_log_keeps_the_file_and_says_so() -> None:
    log = read_log(SAMPLES / "corridor_loop.csv")
    model = OdometryError(range_m_per_sqrt_m=0.01, heading_drift_bias_rad_per_m=0.003)
    check = check_file(log, load_robot("p3at"), model)
    assert not check.checked and check.model == model
    assert check.summary() == "odometry error not checked (no laser in the log)"


def revisited_loop(
    turn_scale: float,
) -> tuple[PoseTrack, PoseTrack, npt.NDArray[np.intp], list[Closure]]:
    """Three laps of a rectangle: the odometry turns ``turn_scale`` more per radian than the
    truth, with a little random error; a node every 10th pose, and a closure (the truth's
    relative pose, as a perfect registration gives it) between each node and every later one
    8 m of path and more on that lies within 0.5 m of it."""
    lap = [[0.0, 0.0], [8.0, 0.0], [8.0, 5.0], [0.0, 5.0]]
    path = WaypointPath(waypoints=np.asarray([*lap, *lap, *lap, [0.0, 0.5]]), speed_m_s=0.5)
    truth = trajectory(path, 5.0)
    errors = OdometryErrorModel(
        turn_scale_error=turn_scale,
        scale_error=0.0,
        heading_drift_rad_per_m=0.0,
        sigma_dist_per_sqrt_m=0.005,
        sigma_turn_per_sqrt_rad=0.005,
    )
    odometry = odometry_from_truth(truth, errors, np.random.default_rng(5))
    nodes = np.arange(0, len(truth), 10, dtype=np.intp)
    x, y, th = truth.x_m[nodes], truth.y_m[nodes], truth.theta_rad[nodes]
    walked = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
    closures = []
    for i in range(len(nodes)):
        for j in range(i + 1, len(nodes)):
            if walked[j] - walked[i] >= 8.0 and math.hypot(x[j] - x[i], y[j] - y[i]) < 0.5:
                c, s = math.cos(th[i]), math.sin(th[i])
                dx, dy = x[j] - x[i], y[j] - y[i]
                closures.append(
                    Closure(i, j, c * dx + s * dy, -s * dx + c * dy, float(th[j] - th[i]), 1.0)
                )
    return odometry, truth, nodes, closures


@pytest.mark.parametrize(
    ("true_turn", "file_turn", "applied"),
    [(0.03, 0.03, True), (0.0, 0.03, False), (0.03, -0.03, False)],
)
def test_revisits_drop_a_bias_they_contradict_and_keep_one_that_agrees(
    true_turn: float, file_turn: float, applied: bool
) -> None:
    odometry, _, nodes, closures = revisited_loop(true_turn)
    assert len(closures) >= 8
    model = OdometryError(
        range_m_per_sqrt_m=0.01,
        bearing_rad_per_sqrt_rad=0.02,
        bearing_rad_per_rad=abs(file_turn),
        turn_scale_bias=file_turn,
    )
    noise = StepNoise.of(model.random_part())

    def on_revisits(m: OdometryError) -> RevisitFactor:
        return revisit_factor(correct_track(odometry, m), nodes, closures, noise, 0.01, 0.002)

    kept, contradicted, unconfirmed = biases_on_revisits(model, on_revisits)
    assert (kept.turn_scale_bias == file_turn) is applied
    assert (kept.bearing_rad_per_rad == abs(file_turn)) is applied
    assert unconfirmed == ()
    if applied:
        assert contradicted == ()
    else:
        ((key, n, statistic),) = contradicted
        assert key == "turn_scale_bias" and n == len(closures)
        assert statistic > 4.0
        check = FileCheck(kept, True, contradicted=contradicted)
        assert "turn_scale_bias not corrected (this log's" in check.summary()
        assert check.as_dict()["biases_contradicted_by_revisits"] == {
            key: {"revisits": n, "likelihood_ratio_statistic": statistic}
        }


def test_a_bias_the_revisits_lean_against_stands_only_if_the_laser_confirms_it() -> None:
    model = OdometryError(
        range_m_per_sqrt_m=0.01,
        bearing_rad_per_sqrt_rad=0.02,
        bearing_rad_per_rad=0.03,
        turn_scale_bias=0.03,
        heading_drift_rad_per_m=0.002,
        heading_drift_bias_rad_per_m=0.002,
    )

    def leaning(m: OdometryError) -> RevisitFactor:
        # 3 revisits that the track corrected by the turn scale fits a little worse: the
        # statistic 12 ln 1.2 = 2.2, short of contradicting it (4); the drift changes nothing
        return RevisitFactor(1.2 if m.turn_scale_bias else 1.0, 3)

    kept, contradicted, unconfirmed = biases_on_revisits(model, leaning)
    assert contradicted == ()
    ((key, n, statistic),) = unconfirmed
    assert (key, n) == ("turn_scale_bias", 3)
    assert statistic == pytest.approx(12.0 * math.log(1.2))
    assert kept.turn_scale_bias == 0.0 and kept.bearing_rad_per_rad == 0.0
    assert kept.heading_drift_bias_rad_per_m == 0.002  # statistic 0: nothing to weigh it with
    assert kept.bearing_rad_per_sqrt_rad == model.bearing_rad_per_sqrt_rad  # walks untouched
    check = FileCheck(kept, True, unconfirmed=unconfirmed)
    assert "turn_scale_bias not corrected (this log's 3 revisits lean against it" in (
        check.summary()
    )
    assert set(check.as_dict()["biases_not_confirmed"]) == {"turn_scale_bias"}
    # the laser's confirmation keeps it
    kept, contradicted, unconfirmed = biases_on_revisits(model, leaning, {"turn_scale_bias"})
    assert kept == model and contradicted == () and unconfirmed == ()


def test_without_revisits_the_file_s_biases_stand() -> None:
    odometry, _, nodes, _ = revisited_loop(0.03)
    model = OdometryError(
        bearing_rad_per_sqrt_rad=0.02, bearing_rad_per_rad=0.03, turn_scale_bias=0.03
    )
    noise = StepNoise.of(model.random_part())

    def without_revisits(m: OdometryError) -> RevisitFactor:
        return revisit_factor(correct_track(odometry, m), nodes, [], noise, 0.01, 0.002)

    assert biases_on_revisits(model, without_revisits) == (model, (), ())


def test_a_laser_log_keeps_a_bias_its_odometry_has_not_one_it_has_not(laser_log: RangeLog) -> None:
    # the same two laps with odometry that drifts 0.02 rad/m: its laser shows the drift, so
    # the file's is corrected; a turn scale the odometry does not have is not
    errors = OdometryErrorModel(
        turn_scale_error=0.0,
        scale_error=0.0,
        heading_drift_rad_per_m=0.02,
        sigma_dist_per_sqrt_m=0.0,
        sigma_turn_per_sqrt_rad=0.0,
    )
    truth = laser_log.truth
    assert truth is not None
    odometry = odometry_from_truth(truth, errors, np.random.default_rng(3))
    log = dataclasses.replace(laser_log, poses=odometry)
    model = OdometryError(
        heading_drift_rad_per_m=0.02,
        heading_drift_bias_rad_per_m=0.02,
        bearing_rad_per_rad=0.03,
        turn_scale_bias=0.03,
    )
    check = check_file(log, load_robot("p3at-lms200"), model)
    assert check.checked
    assert check.model.heading_drift_bias_rad_per_m == 0.02
    assert check.model.turn_scale_bias == 0.0


def test_the_likelihood_ratio_of_the_revisits() -> None:
    # 4 n ln(f_corrected / f_uncorrected): positive when the revisits fit better uncorrected
    assert likelihood_ratio(RevisitFactor(2.0, 3), RevisitFactor(1.0, 3)) == pytest.approx(
        12.0 * math.log(2.0)
    )
    assert likelihood_ratio(RevisitFactor(1.0, 3), RevisitFactor(2.0, 3)) < 0.0
    # the same errors whitened by a narrower spread (a track a scale correction shrinks) are
    # no worse a fit for it: the determinants take back what the factor gives
    narrow = RevisitFactor(2.0, 3, log_determinant=3 * 2 * math.log(0.25))
    assert likelihood_ratio(narrow, RevisitFactor(1.0, 3)) == pytest.approx(0.0, abs=1e-12)
    # nothing to compare on: no evidence either way
    assert likelihood_ratio(RevisitFactor(math.nan, 0), RevisitFactor(math.nan, 0)) == 0.0
