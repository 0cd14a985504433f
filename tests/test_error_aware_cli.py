"""`gridmap build --mode error-aware` as a user meets it: flags, errors, and what the map shows."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.mapping.mapfile import load_map
from tests.helpers import names, run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
LOG = SAMPLES / "corridor_loop.csv"  # drift 1: odometry off by metres by the end of the loop


def build(tmp_path: Path, name: str, *extra: str) -> np.ndarray:
    out = tmp_path / f"{name}.png"
    code, _, stderr = run("build", str(LOG), "-o", str(out), "--map-mode", "scale", *extra)
    assert code == 0, stderr
    return load_map(out.with_suffix(".yaml")).probability()


def test_error_aware_build_from_a_calibrated_file(tmp_path: Path) -> None:
    cal = tmp_path / "odometry.yaml"
    code, _, stderr = run("calibrate", str(LOG), "-o", str(cal))
    assert code == 0, stderr
    build(tmp_path, "aware", "--mode", "error-aware", "--odometry-error", str(cal))
    sonar_only = build(
        tmp_path, "sonar", "--mode", "error-aware", "--odometry-coefficient", "range_m_per_m=0"
    )
    standard = build(tmp_path, "standard")
    # with every coefficient 0 the error-aware map is the standard map
    assert np.array_equal(sonar_only, standard, equal_nan=True)
    # the expected map over the pose error, the calibrated biases corrected (the default), is
    # truer than the drift-blind map: lower NLL of the world (0.15 against 0.32 when measured)
    assert nll(tmp_path / "aware.yaml") < 0.6 * nll(tmp_path / "standard.yaml")
    # spreading the biases instead of correcting them is truer than ignoring them (0.23), and
    # less true than correcting them
    spread = ("--mode", "error-aware", "--odometry-error", str(cal), "--no-correct-odometry")
    build(tmp_path, "spread", *spread)
    assert nll(tmp_path / "spread.yaml") < 0.85 * nll(tmp_path / "standard.yaml")
    assert nll(tmp_path / "aware.yaml") < nll(tmp_path / "spread.yaml")
    # the analytic fade against its oracle, the expected map, on the same spread: it is
    # measured less true (0.326 against 0.230), and no truer than the standard map (0.320)
    build(tmp_path, "analytic", *spread, "--error-samples", "0")
    assert nll(tmp_path / "spread.yaml") < 0.85 * nll(tmp_path / "analytic.yaml")
    # walls as the trinary map draws them (a scale map's 0.65 is a rescaled probability:
    # 0.46, where the expected map's grey lies)
    assert walls(tmp_path, "aware", "--mode", "error-aware", "--odometry-error", str(cal)) < (
        0.5 * walls(tmp_path, "standard")
    )


def walls(tmp_path: Path, name: str, *extra: str) -> int:
    """Occupied cells of the trinary map (p >= 0.65) of LOG built with ``extra``."""
    out = tmp_path / f"{name}_trinary.pgm"
    code, _, stderr = run("build", str(LOG), "-o", str(out), *extra)
    assert code == 0, stderr
    return int(np.count_nonzero(load_map(out.with_suffix(".yaml")).occupancy == 100))


def nll(map_yaml: Path) -> float:
    """NLL of the corridor world under the map, as ``gridmap evaluate`` scores it."""
    from gridmap_cli.evaluation.evaluate import (
        evaluate_map,
        load_probability_map,
        load_truth,
        odometry_frame_in_world,
        sensed_region,
    )
    from gridmap_cli.poses.sync import sensors_for_log
    from gridmap_cli.readers import read_log
    from gridmap_cli.robot import load_robot

    truth = load_truth(SAMPLES / "worlds" / "corridor_loop.yaml")
    log = read_log(LOG)
    assert log.truth is not None
    region = sensed_region(truth.world, log.truth, sensors_for_log(log, load_robot("p3at")))
    pmap = load_probability_map(map_yaml)
    start = odometry_frame_in_world(log)
    return evaluate_map(pmap, truth.walls, truth.spec, region, start).nll


@pytest.mark.parametrize("log", ["csv", "laser"])
def test_a_perfect_odometry_file_gives_the_standard_map_byte_for_byte(
    tmp_path: Path, log: str
) -> None:
    source, extra = LOG, ()
    if log == "laser":
        source = tmp_path / "laser.2d"
        code, _, stderr = run(
            "simulate", str(SAMPLES / "worlds" / "office.yaml"),
            str(SAMPLES / "paths" / "office.yaml"), "--robot", "p3at-lms200", "--duration", "20",
            "-o", str(source),
        )  # fmt: skip
        assert code == 0, stderr
        # the odometry both times: by default a laser log is mapped with the pose graph
        extra = ("--robot", "p3at-lms200", "--pose", "odometry")
    perfect = tmp_path / "perfect.yaml"
    perfect.write_text("gridmap-odometry-error: 1\n")  # the version line alone
    outputs = []
    for name, mode in (("standard", ()), ("aware", ("--mode", "error-aware"))):
        out = tmp_path / f"{name}.pgm"
        args = [*mode, "--odometry-error", str(perfect)] if mode else []
        code, _, stderr = run("build", str(source), "-o", str(out), *extra, *args)
        assert code == 0, stderr
        outputs.append((out.read_bytes(), out.with_suffix(".yaml").read_text()))
    assert outputs[0][0] == outputs[1][0]
    # the YAML names the image; everything else is the same
    assert outputs[0][1].replace("standard", "aware") == outputs[1][1]


def test_error_samples_choose_the_map_and_repeat_it(tmp_path: Path) -> None:
    flags = ("--mode", "error-aware", "--odometry-coefficient", "heading_drift_rad_per_m=0.005")
    maps = {}
    for name, k in (("a", "4"), ("b", "4"), ("analytic", "0")):
        out = tmp_path / f"{name}.pgm"
        code, _, stderr = run("build", str(LOG), "-o", str(out), *flags, "--error-samples", k)
        assert code == 0, stderr
        maps[name] = out.read_bytes()
    assert maps["a"] == maps["b"]  # the same seed, the same tracks, the same map
    assert maps["a"] != maps["analytic"]


def test_coefficients_from_flags_override_the_file(tmp_path: Path) -> None:
    cal = tmp_path / "odometry.yaml"
    cal.write_text("gridmap-odometry-error: 1\nrange_m_per_m: 0.0\n")
    plain = build(tmp_path, "plain", "--mode", "error-aware", "--odometry-error", str(cal))
    spread = build(
        tmp_path,
        "spread",
        "--mode",
        "error-aware",
        "--odometry-error",
        str(cal),
        "--odometry-coefficient",
        "range_m_per_m=0.05",
    )

    # walls as the map states them (p >= 0.65; map_server's occupancy of a scale map is 65 from
    # p = 0.51 on, which the fringe of cells few samples saw reaches)
    stored = {n: load_map(tmp_path / f"{n}.yaml").stored_probability() for n in ("plain", "spread")}
    assert spread.shape != plain.shape  # the samples' readings land past the standard grid
    assert np.count_nonzero(stored["spread"] >= 0.65) < 0.5 * np.count_nonzero(
        stored["plain"] >= 0.65
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--mode", "error-aware"], "needs the odometry error"),
        (["--odometry-coefficient", "range_m_per_m=0.01"], "apply to --mode error-aware"),
        (["--trust-length", "0.5"], "apply to --mode error-aware"),
        (["--error-samples", "4"], "--error-samples applies to --mode error-aware"),
        (
            [
                "--mode",
                "error-aware",
                "--odometry-coefficient",
                "range_m_per_m=0",
                "--error-samples",
                "-1",
            ],
            "Invalid value for '--error-samples'",
        ),
        (["--mode", "error-aware", "--odometry-coefficient", "speed=1"], "NAME one of"),
        (["--mode", "error-aware", "--odometry-coefficient", "range_m_per_m=x"], "not a number"),
        (["--mode", "error-aware", "--odometry-coefficient", "range_m_per_m=-1"], ">= 0"),
        (
            [
                "--mode",
                "error-aware",
                "--odometry-coefficient",
                "range_m_per_m=0",
                "--trust-length",
                "0",
            ],
            "--trust-length",
        ),
    ],
)
def test_bad_error_aware_flags_are_usage_errors(
    tmp_path: Path, args: list[str], message: str
) -> None:
    code, _, stderr = run("build", str(LOG), "-o", str(tmp_path / "m.png"), *args)
    assert code == 2
    assert message in stderr
    assert names(tmp_path) == set()


def test_bad_odometry_file_names_it_and_writes_nothing(tmp_path: Path) -> None:
    cal = tmp_path / "odometry.yaml"
    cal.write_text("gridmap-odometry-error: 1\nrange_m_per_m: lots\n")
    out = tmp_path / "out"
    out.mkdir()
    code, _, stderr = run(
        "build", str(LOG), "-o", str(out / "m.png"), "--mode", "error-aware",
        "--odometry-error", str(cal),
    )  # fmt: skip
    assert code == 1
    assert "odometry.yaml" in stderr and "range_m_per_m" in stderr
    assert names(out) == set()


def test_error_aware_maps_laser_and_mixed_logs(tmp_path: Path) -> None:
    log = tmp_path / "laser.2d"
    code, _, stderr = run(
        "simulate", str(SAMPLES / "worlds" / "office.yaml"), str(SAMPLES / "paths" / "office.yaml"),
        "--robot", "p3at-lms200", "--duration", "3", "-o", str(log),
    )  # fmt: skip
    assert code == 0, stderr
    maps = {}
    for name, extra in (("mixed", ()), ("laser", ("--sensors", "laser1_*"))):
        out = tmp_path / f"{name}.png"
        code, _, stderr = run(
            "build", str(log), "-o", str(out), "--robot", "p3at-lms200", "--map-mode", "scale",
            "--mode", "error-aware", "--odometry-coefficient", "range_m_per_m=0.01", *extra,
        )  # fmt: skip
        assert code == 0, stderr
        maps[name] = load_map(out.with_suffix(".yaml")).probability()
    for prob in maps.values():
        known = prob[~np.isnan(prob)]
        # three seconds of driving: the walls are known (dark) and the room mostly free
        assert np.count_nonzero(known >= 0.65) > 50
        assert np.count_nonzero(known <= 0.25) > 0.5 * known.size
    # the sonars add what their cones see: the mixed map knows more cells
    assert np.count_nonzero(~np.isnan(maps["mixed"])) > np.count_nonzero(~np.isnan(maps["laser"]))


def test_undecided_trinary_map_warns_and_suggests_scale() -> None:
    import numpy as np

    from gridmap_cli.cli.build import undecided_note

    mostly_grey = np.array([[0.5, 0.45, 0.55], [0.1, np.nan, 0.9]])
    (note,) = undecided_note(mostly_grey, 0.65, 0.25)
    assert note.startswith("60 % of the observed cells") and "--map-mode scale" in note
    assert undecided_note(np.array([[0.1, 0.9, 0.5]]), 0.65, 0.25) == ()


def test_readings_beyond_the_heading_spread_limit_are_left_out(tmp_path: Path) -> None:
    # heading drift 0.1 rad/m: g passes 30 deg after 5.2 m of the 56 m lap, and every later
    # reading is left out (weight 0); with no limit they blur over wedges up to 90 deg
    from gridmap_cli.evaluation.evaluate import load_probability_map

    sample = Path(__file__).resolve().parents[1] / "samples" / "corridor_loop.csv"
    known = []
    for limit in ("30", "inf"):
        out = tmp_path / f"map{limit}.png"
        code, _, err = run(
            "build", str(sample), "-o", str(out), "--mode", "error-aware", "--map-mode", "scale",
            "--odometry-coefficient", "heading_drift_rad_per_m=0.1", "--max-heading-spread",
            limit, "--quiet",
        )  # fmt: skip
        assert code == 0, err
        known.append(int((~np.isnan(load_probability_map(out.with_suffix(".yaml")).prob)).sum()))
    assert known[0] < 0.5 * known[1]
    code, _, err = run("build", str(sample), "-o", str(tmp_path / "s.png"),
                           "--max-heading-spread", "10")  # fmt: skip
    assert code == 2 and "apply to --mode error-aware" in err


def test_an_error_aware_map_of_the_reference_track_warns_that_it_blurs_for_nothing(
    tmp_path: Path,
) -> None:
    sample = Path(__file__).resolve().parents[1] / "samples" / "corridor_loop.csv"
    args = ["build", str(sample), "--pose", "global", "--mode", "error-aware",
            "--error-samples", "2", "--map-mode", "scale"]  # fmt: skip
    code, _, err = run(*args, "-o", str(tmp_path / "a.png"),
                       "--odometry-coefficient", "range_m_per_m=0.05")  # fmt: skip
    assert code == 0, err
    assert "Warning: --pose global --mode error-aware: the odometry's error is spread" in err
    # a perfect-odometry spread (the reference maps of make experiment) says nothing
    code, _, err = run(*args, "-o", str(tmp_path / "b.png"),
                       "--odometry-coefficient", "range_m_per_m=0")  # fmt: skip
    assert code == 0, err
    assert "Warning" not in err
