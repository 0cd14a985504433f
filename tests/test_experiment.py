"""bench/experiment.py: a mode is a list of build arguments, so adding one is one entry."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "bench" / "experiment.py"


@pytest.fixture
def experiment() -> Iterator[ModuleType]:
    spec = importlib.util.spec_from_file_location("experiment", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["experiment"] = module
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("experiment", None)


def test_modes_default_to_their_name_and_take_the_calibration_file(
    experiment: ModuleType, monkeypatch: pytest.MonkeyPatch
) -> None:
    cal = Path("/x/calibration_drift1.yaml")
    assert experiment.mode_args("standard", cal) == ["--mode", "standard"]
    monkeypatch.setitem(
        experiment.MODE_ARGS,
        "error-aware",
        ["--mode", "error-aware", "--odometry-error", "{calibration}"],
    )
    assert experiment.mode_args("error-aware", cal) == [
        "--mode", "error-aware", "--odometry-error", str(cal),
    ]  # fmt: skip


def test_mean_and_spread_over_seeds(experiment: ModuleType) -> None:
    assert experiment.mean_sd([0.5, 0.7]) == "0.600 ± 0.141"
    assert experiment.mean_sd([0.5]) == "0.500"
    assert experiment.mean_sd([float("nan")]) == "n/a"
