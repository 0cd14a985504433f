"""bench/experiment.py: a mode is a list of build arguments, so adding one is one entry."""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from gridmap_cli.evaluation.evaluate import ProbabilityMap, Truth, evaluate_map
from gridmap_cli.mapping.grid import GridSpec
from gridmap_cli.poses.odometry_error import OdometryError
from gridmap_cli.sim.world import World
from tests.helpers import bench_script


@pytest.fixture
def experiment() -> Iterator[ModuleType]:
    yield from bench_script("experiment")


def test_modes_default_to_their_name_and_take_the_calibration_file(
    experiment: ModuleType,
) -> None:
    cal = Path("/x/calibration_drift1.yaml")
    # a mode MODE_ARGS does not list runs as --mode NAME (gridmap build checks the name)
    assert "new-mode" not in experiment.MODE_ARGS
    assert experiment.mode_args("new-mode", cal) == ["--mode", "new-mode"]
    assert experiment.mode_args("standard", cal) == ["--mode", "standard"]
    # {calibration} becomes the drift level's odometry-error file
    assert experiment.mode_args("error-aware", cal) == [
        "--mode", "error-aware", "--odometry-error", str(cal),
    ]  # fmt: skip


def test_mean_and_spread_over_seeds(experiment: ModuleType) -> None:
    assert experiment.mean_sd([0.5, 0.7]) == "0.600 ± 0.141"
    assert experiment.mean_sd([0.5]) == "0.500"
    assert experiment.mean_sd([float("nan")]) == "n/a"


def test_figure_draws_each_run_from_its_evaluation(experiment: ModuleType, tmp_path: Path) -> None:
    # one world, one mode, two drift levels: the figure needs only the runs and the truths
    walls = np.zeros((4, 6), dtype=bool)
    walls[:, 5] = True
    spec = GridSpec(0.0, 0.0, 1.0, 6, 4)
    truth = Truth(spec, walls, World(walls, spec), np.ones(spec.shape, dtype=bool))
    pmap = ProbabilityMap(spec, np.where(walls, 0.9, 0.1), 0.65)
    e = evaluate_map(pmap, walls, spec)
    runs = [
        experiment.Run("w", d, 21, "standard", e, tmp_path / "absent.yaml", (0.0, 0.0, 0.0))
        for d in (0.0, 1.0)
    ]
    out = tmp_path / "maps.png"
    experiment.figure(runs, {"w": truth}, (0.0, 1.0), out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_doc_states_the_simulators_drift_one_errors(
    experiment: ModuleType, tmp_path: Path
) -> None:
    walls = np.zeros((4, 6), dtype=bool)
    spec = GridSpec(0.0, 0.0, 1.0, 6, 4)
    e = evaluate_map(ProbabilityMap(spec, np.full(spec.shape, 0.1), 0.65), walls, spec)
    runs = [experiment.Run("w", 1.0, 21, "standard", e, tmp_path / "m.yaml", (0.0, 0.0, 0.0))]
    args = argparse.Namespace(worlds=("w",), drifts=(1.0,), seeds=(21,))
    doc = experiment.write_doc(runs, {"1": OdometryError().as_dict()}, args, 1.0, None)
    # OdometryErrorModel's defaults in the table's column order; 0.2 deg/m of heading drift
    assert "(The simulator's drift-1 errors: 0.01, 0.01, 0.02, 0.02, 0.00349; drift 2" in doc
    # the closing line counts the simulated maps, and the real ones when there are any
    assert "(1 simulated maps)." in doc
    doc = experiment.write_doc(
        runs, {"1": OdometryError().as_dict()}, args, 1.0, None,
        ("39 CARMEN maps, references included", "25 s of scan matching"),
    )  # fmt: skip
    assert "(1 simulated maps, 39 CARMEN maps, references included, 25 s of scan matching)." in doc
