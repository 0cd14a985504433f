"""bench/closure_trace.py: what it refuses before it runs anything (the shared data need not be
there)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from tests.helpers import bench_script


@pytest.fixture
def bench() -> Iterator[ModuleType]:
    yield from bench_script("closure_trace", "real_logs", "slam_stress")


def _refused(bench: ModuleType, argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    with pytest.raises(SystemExit) as exit_info:
        bench.main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    return err[-1]


def test_a_log_that_is_not_a_bag_is_refused_with_one_line(
    bench: ModuleType, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _refused(bench, ["seattle", "--bag"], capsys).endswith("error: no bag 'seattle'")


def test_a_reference_by_scan_index_is_refused_for_a_variant_that_drops_scans(
    bench: ModuleType, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    reference = tmp_path / "aces-full.npz"
    np.savez(reference, track=np.zeros((3, 3)))
    line = _refused(
        bench, ["aces", "--bag", "--variant", "every-2", "--reference", str(reference)], capsys
    )
    assert line.endswith("every-2 drops scans: a reference by scan index does not apply")


def test_a_missing_reference_is_refused(
    bench: ModuleType, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    missing = tmp_path / "none.npz"
    line = _refused(bench, ["aces", "--bag", "--reference", str(missing)], capsys)
    assert line.endswith(f"{missing} is not there")
    assert not missing.exists()
