"""The C heap kept for reuse during a build (glibc only)."""

from __future__ import annotations

import sys

import pytest

from gridmap_cli import heap
from gridmap_cli.heap import keep_scratch_memory


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="mallopt is glibc's")
def test_glibc_takes_the_thresholds() -> None:
    assert keep_scratch_memory() is True


def test_trim_every_n_calls_trims_on_every_nth(monkeypatch: pytest.MonkeyPatch) -> None:
    trims: list[int] = []
    monkeypatch.setattr(heap, "release_free_memory", lambda: trims.append(1) or True)
    trim = heap.TrimEvery(3)
    for _ in range(10):
        trim()
    assert len(trims) == 3  # calls 3, 6 and 9
