"""build --correct-odometry: a known bias is taken out of the track, not blurred."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.evaluation.evaluate import odometry_frame_in_world
from gridmap_cli.mapping.mapfile import load_map
from gridmap_cli.poses.calibration.calibrate import calibrate
from gridmap_cli.poses.odometry_error import correct_track, save_odometry_error
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import load_robot
from gridmap_cli.sim.odometry import OdometryErrorModel
from gridmap_cli.sim.path import load_path
from gridmap_cli.sim.simulate import simulate
from gridmap_cli.sim.world import World
from gridmap_cli.writers.csv_log import save_csv_log
from tests.helpers import built, names, run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
#: A robot whose wheels are off by 4 % and whose turns by -5 %, with little random error.
BIASED = OdometryErrorModel(
    scale_error=0.04,
    turn_scale_error=-0.05,
    heading_drift_rad_per_m=0.002,
    sigma_dist_per_sqrt_m=0.002,
    sigma_turn_per_sqrt_rad=0.002,
)


def biased_log(seed: int) -> RangeLog:
    loaded = load_map(SAMPLES / "worlds" / "corridor_loop.yaml")
    return simulate(
        World(loaded.occupied_mask(), loaded.spec),
        load_path(SAMPLES / "paths" / "corridor_loop.yaml"),
        load_robot("p3at"),
        seed=seed,
        error_model=BIASED,
    )


def track_error_m(track: PoseTrack, log: RangeLog) -> float:
    """RMS distance between ``track`` (odometry frame) and the log's truth, placed by the first
    true pose."""
    x0, y0, th0 = odometry_frame_in_world(log)
    c, s = np.cos(th0), np.sin(th0)
    x = x0 + c * track.x_m - s * track.y_m
    y = y0 + s * track.x_m + c * track.y_m
    truth = log.truth
    assert truth is not None
    return float(np.sqrt(np.mean((x - truth.x_m) ** 2 + (y - truth.y_m) ** 2)))


def test_calibrated_on_one_run_the_correction_brings_another_closer_to_the_truth() -> None:
    model = calibrate(biased_log(seed=1)).model
    assert model.distance_scale_bias == pytest.approx(BIASED.scale_error, abs=0.01)
    assert model.turn_scale_bias == pytest.approx(BIASED.turn_scale_error, abs=0.01)
    held_out = biased_log(seed=2)
    before = track_error_m(held_out.poses, held_out)
    after = track_error_m(correct_track(held_out.poses, model), held_out)
    assert before > 1.0  # metres: the bias is plain
    assert after < 0.25 * before


def test_build_corrects_in_either_mode(tmp_path: Path) -> None:
    log = biased_log(seed=1)
    path = tmp_path / "run.csv"
    save_csv_log(log, path)
    odo = tmp_path / "odo.yaml"
    save_odometry_error(calibrate(log).model, odo)
    assert odo.read_text().startswith("gridmap-odometry-error: 3")
    plain = built(tmp_path, "plain", str(path))
    fixed = built(tmp_path, "fixed", str(path), "--odometry-error", str(odo), "--correct-odometry")
    assert plain[0] != fixed[0]
    ea = ("--mode", "error-aware", "--odometry-error", str(odo), "--error-samples", "2")
    blurred = built(tmp_path, "ea", str(path), *ea, "--no-correct-odometry")
    corrected = built(tmp_path, "ea-fixed", str(path), *ea, "--correct-odometry")
    assert blurred[0] != corrected[0]


def test_error_aware_corrects_known_biases_by_default_and_says_so(tmp_path: Path) -> None:
    log = biased_log(seed=1)
    path = tmp_path / "run.csv"
    save_csv_log(log, path)
    odo = tmp_path / "odo.yaml"
    save_odometry_error(calibrate(log).model, odo)
    ea = ("--mode", "error-aware", "--odometry-error", str(odo), "--error-samples", "2")
    default = built(tmp_path, "default", str(path), *ea)
    corrected = built(tmp_path, "corrected", str(path), *ea, "--correct-odometry")
    blurred = built(tmp_path, "blurred", str(path), *ea, "--no-correct-odometry")
    assert default == corrected
    assert default[0] != blurred[0]
    out = tmp_path / "said"
    out.mkdir()
    code, stdout, err = run("build", str(path), "-o", str(out / "m.png"), *ea, "--json")
    assert code == 0
    assert "the odometry's calibrated biases corrected" in err
    assert '"odometry_corrected": true' in stdout
    code, stdout, err = run("build", str(path), "-o", str(out / "n.png"), *ea, "--json",
                            "--no-correct-odometry")  # fmt: skip
    assert code == 0
    assert "biases corrected" not in err and "odometry_corrected" not in stdout


def test_the_default_corrects_nothing_it_cannot(tmp_path: Path) -> None:
    """Standard mode, a reference track and a file without signed biases: no correction by
    default, and no error for the flag not given (the explicit flag is refused where it cannot
    apply)."""
    v1 = tmp_path / "v1.yaml"
    v1.write_text("gridmap-odometry-error: 1\nrange_m_per_m: 0.02\n")
    log = str(SAMPLES / "corridor_loop.csv")
    ea = ("--mode", "error-aware", "--error-samples", "2")
    old = built(tmp_path, "v1", log, *ea, "--odometry-error", str(v1))
    assert old == built(tmp_path, "v1-no", log, *ea, "--odometry-error", str(v1),
                        "--no-correct-odometry")  # fmt: skip
    assert built(tmp_path, "std", log) == built(tmp_path, "std-no", log, "--no-correct-odometry")
    v3 = tmp_path / "v3.yaml"
    v3.write_text(
        "gridmap-odometry-error: 3\ndistance_scale_bias: 0.05\nrange_m_per_sqrt_m: 0.01\n"
    )
    # a reference track has no odometry to correct: no error for the flag not given (it is
    # one when given), and the same map as --no-correct-odometry
    ref = ("--pose", "global", *ea, "--odometry-error", str(v3))
    assert built(tmp_path, "ref", log, *ref) == built(tmp_path, "ref-no", log, *ref,
                                                      "--no-correct-odometry")  # fmt: skip
    out = tmp_path / "refused"
    out.mkdir()
    code, _, err = run("build", log, "-o", str(out / "m.png"), *ref, "--correct-odometry")
    assert code == 2 and "--correct-odometry corrects the robot's own odometry" in err
    # standard mode stays drift-blind: it does not take the file unless told to correct
    code, _, err = run("build", log, "-o", str(out / "m.png"), "--odometry-error", str(v3))
    assert code == 2 and "apply to --mode error-aware" in err
    assert names(out) == set()


@pytest.mark.parametrize("mode", [(), ("--mode", "error-aware")])
def test_a_perfect_odometry_file_corrects_nothing(tmp_path: Path, mode: tuple[str, ...]) -> None:
    perfect = tmp_path / "perfect.yaml"
    perfect.write_text("gridmap-odometry-error: 1\n")
    log = str(SAMPLES / "corridor_loop.csv")
    plain = built(tmp_path, "plain", log, *mode, *(("--odometry-error", str(perfect)) * bool(mode)))
    fixed = built(tmp_path, "fixed", log, *mode, "--odometry-error", str(perfect),
                  "--correct-odometry")  # fmt: skip
    assert plain == fixed


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ([], "Error: --correct-odometry needs the odometry's biases: --odometry-error FILE"),
        (["--odometry-error", "{v1}"], "holds systematic errors without their signs"),
        (
            ["--odometry-error", "{v3}", "--pose", "global"],
            "Error: --correct-odometry corrects the robot's own odometry",
        ),
        (
            ["--odometry-error", "{v3}", "--odometry-coefficient", "range_m_per_m=0"],
            "Error: --odometry-coefficient, --trust-length and --max-heading-spread apply to",
        ),
    ],
)
def test_bad_combinations_are_usage_errors(tmp_path: Path, args: list[str], message: str) -> None:
    v1 = tmp_path / "v1.yaml"
    v1.write_text("gridmap-odometry-error: 1\nrange_m_per_m: 0.02\n")
    v3 = tmp_path / "v3.yaml"
    v3.write_text("gridmap-odometry-error: 3\ndistance_scale_bias: 0.02\n")
    out = tmp_path / "out"
    out.mkdir()
    args = [a.format(v1=v1, v3=v3) for a in args]
    code, _, err = run(
        "build", str(SAMPLES / "corridor_loop.csv"), "-o", str(out / "m.png"),
        "--correct-odometry", *args,
    )  # fmt: skip
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1
    assert names(out) == set()
