"""bench/slam_relations.py: the SLAM benchmark table, and its section of the results page that
bench/scan_match.py keeps when it rewrites the page."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest

from gridmap_cli.evaluation.relations import RelationScore
from tests.helpers import bench_script


@pytest.fixture
def bench() -> Iterator[ModuleType]:
    yield from bench_script("slam_relations")


def _scores(bench: ModuleType, name: str, slam_m: float) -> object:
    score = {
        t: RelationScore(100, 2, m, 0.5 * m, 10 * m, 5 * m)
        for t, m in (("odometry", 7.0), ("scan-matched", 0.3), ("slam", slam_m))
    }
    return bench.LogScores(name, score, closures=12, scans=910, seconds=20.0, offset_s=70.18)


def test_the_table_puts_each_track_beside_the_published_figures(bench: ModuleType) -> None:
    lines = bench.table([_scores(bench, "intel", 0.094)])
    header, _, row = lines
    assert header.split("|")[3:6] == [" odometry ", " scan-matched ", " slam "]
    cells = [c.strip() for c in row.split("|")[1:-1]]
    assert cells[0] == "intel" and cells[1] == "100"
    assert cells[4] == "0.094 ± 0.047 m, 0.94 ± 0.47°"
    assert cells[5:] == ["0.070 m", "0.031 m", "0.023 m"]  # GMapping, graph mapping, Cartographer


def test_the_section_replaces_its_old_self_and_scan_match_keeps_it(
    bench: ModuleType, tmp_path: Path
) -> None:
    page = tmp_path / "results.md"
    page.write_text("# Scan matching\n\nthe rest of the page\n")
    bench.write_section([_scores(bench, "aces", 0.5)], page)
    bench.write_section([_scores(bench, "aces", 0.157)], page)
    text = page.read_text()
    assert text.count(bench.BEGIN) == 1 and "0.157 ± 0.079 m" in text and "0.500" not in text
    assert text.startswith("# Scan matching\n\nthe rest of the page\n")
    kept = bench.kept_section(page)
    assert kept is not None and kept.startswith(bench.BEGIN) and kept.endswith(bench.END)
    assert "0.157" in kept and bench.kept_section(tmp_path / "absent.md") is None
