"""bench/carmen_experiment.py: the claim lines say met or missed from the ratios they show."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from types import ModuleType, SimpleNamespace

import pytest

from tests.helpers import bench_script


@pytest.fixture
def carmen() -> Iterator[ModuleType]:
    yield from bench_script("carmen_experiment")


def runs(carmen: ModuleType, nll: dict[tuple[str, str, str], float], drift: dict[str, float]):
    return [
        carmen.RealRun(log, part, mode, SimpleNamespace(nll=v), Path(), (0.0, 0.0, 0.0), drift[log])
        for (log, part, mode), v in nll.items()
    ]


def scores(ea: dict[tuple[str, str], float]) -> dict[tuple[str, str, str], float]:
    """Every drift-blind mode at NLL 1 except standard-corrected at 0.5, error-aware as given."""
    out = {}
    for (log, part), v in ea.items():
        out |= {(log, part, "standard"): 1.0, (log, part, "standard-corrected"): 0.5}
        out |= {(log, part, "error-aware-perfect"): 1.0, (log, part, "error-aware"): v}
    return out


def test_the_claim_is_met_when_every_bound_holds(carmen: ModuleType) -> None:
    ea = {("a", "first half"): 0.40, ("a", "second half"): 0.42,
          ("b", "first half"): 0.50, ("b", "second half"): 0.45}  # fmt: skip
    lines = carmen.claim_lines(runs(carmen, scores(ea), {"a": 30.0, "b": 5.0}))
    text = "\n".join(lines)
    assert (
        "| a | first half | second half | 30.0 | 0.400 | standard-corrected | 0.500 | 0.800 |"
        in text
    )
    assert "worst 1.000, met" in text
    assert "most drifting log (a, its odometry 30 m off): worst half 0.840, met" in text
    assert "mean <= 0.93: 0.885, met" in text


def test_one_bad_half_misses_two_bounds(carmen: ModuleType) -> None:
    ea = {("a", "first half"): 0.40, ("a", "second half"): 0.60,
          ("b", "first half"): 0.40, ("b", "second half"): 0.40}  # fmt: skip
    text = "\n".join(carmen.claim_lines(runs(carmen, scores(ea), {"a": 30.0, "b": 5.0})))
    assert "worst 1.200, missed" in text
    assert "worst half 1.200, missed" in text
    assert "mean <= 0.93: 0.900, met" in text


def test_another_logs_calibration_is_shown_apart_from_the_claim(carmen: ModuleType) -> None:
    other = ("first half, other log", "second half, other log")
    ea = {("intel", "first half"): 0.40, ("intel", "second half"): 0.40,
          ("intel", other[0]): 0.55, ("intel", other[1]): 0.45}  # fmt: skip
    text = "\n".join(carmen.claim_lines(runs(carmen, scores(ea), {"intel": 30.0})))
    assert (
        "| intel | first half | aces (whole) | 30.0 | 0.550 | standard-corrected | 0.500 " in text
    )
    assert "1.100 **over** |" in text
    # the claim's mean is over the halves calibrated on the other half alone
    assert "mean <= 0.93: 0.800, met" in text
    assert (
        "another log's calibration, <= 1.02x on every half: worst 1.100, missed (mean 1.000)"
        in text
    )
