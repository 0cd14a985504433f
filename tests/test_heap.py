"""The C heap kept for reuse during a build (glibc only)."""

from __future__ import annotations

import sys

import pytest

from gridmap_cli.heap import keep_scratch_memory


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="mallopt is glibc's")
def test_glibc_takes_the_thresholds() -> None:
    assert keep_scratch_memory() is True
