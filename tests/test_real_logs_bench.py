"""bench/real_logs.py: the table of every shared real log (its frame, not its figures), its
section of the results page, and a clean skip without the shared data."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest

from tests.helpers import bench_script


@pytest.fixture
def bench() -> Iterator[ModuleType]:
    yield from bench_script("real_logs")


def _rows(bench: ModuleType) -> list[object]:
    cell, row = bench.Cell, bench.Row
    bag = row(
        "bag",
        "aces",
        7374,
        1279,
        {
            "odometry": cell((0.56, 2.68, 2.52, 6.14)),
            "scan-matched": cell((0.19, 0.74, 0.57, 1.26), seconds=12.4),
            "slam": cell((0.176, 0.838, 0.45, 0.85), seconds=30.6, note="40 closures"),
        },
    )
    carmen = row(
        "carmen",
        "seattle",
        241,
        241,
        {
            "odometry": cell((2.71,)),
            "scan-matched": cell(error="NoLaserError: no scan"),
            "slam": cell((2.674,), seconds=3.2),
        },
    )
    return [bag, carmen]


def test_each_log_is_a_row_with_a_column_per_pose_source(bench: ModuleType) -> None:
    lines = bench.tables(_rows(bench), bench.SOURCES)
    bag = lines[lines.index("The benchmark's raw logs, on their relations:") + 2 :][:3]
    header = [c.strip() for c in bag[0].split("|")[1:-1]]
    assert header[3:6] == ["odometry", "scan-matched", "slam"]
    cells = [c.strip() for c in bag[2].split("|")[1:-1]]
    assert cells[:3] == ["aces", "7,374", "1,279"]
    assert cells[3] == "0.560 ± 2.680 m, 2.52 ± 6.14°"  # odometry takes no time of its own
    assert cells[5] == "0.176 ± 0.838 m, 0.45 ± 0.85° (31 s)"
    assert cells[6:] == ["0.060 m", "0.044 m", "0.038 m"]  # GMapping, graph mapping, Cartographer
    i = lines.index("The corrected CARMEN logs, APE RMSE against their corrected poses:")
    cells = [c.strip() for c in lines[i + 4].split("|")[1:-1]]
    # a source that failed says so in its cell; the others are still there
    assert cells == [
        "seattle",
        "241",
        "241",
        "2.71 m",
        "failed: NoLaserError: no scan",
        "2.67 m (3 s)",
    ]
    assert "- aces (raw bag): slam: 40 closures" in lines


def test_a_subset_of_sources_gives_only_their_columns(bench: ModuleType) -> None:
    rows = _rows(bench)[1:]
    lines = bench.carmen_table(rows, ("slam",))
    assert [c.strip() for c in lines[0].split("|")[1:-1]] == [
        "log",
        "scans",
        "poses compared",
        "slam",
    ]
    assert lines[2].endswith("| 2.67 m (3 s) |")
    assert not any("raw logs" in line for line in bench.tables(rows, ("slam",)))


def test_the_section_replaces_its_old_self(bench: ModuleType, tmp_path: Path) -> None:
    page = tmp_path / "results.md"
    page.write_text("# Scan matching\n\nthe rest\n")
    rows = _rows(bench)
    bench.write_section(bench.section(rows, bench.SOURCES, 100.0, 80.0, 2), page)
    bench.write_section(bench.section(rows[1:], bench.SOURCES, 50.0, 40.0, 1), page)
    text = page.read_text()
    assert text.startswith("# Scan matching\n\nthe rest\n") and text.count(bench.BEGIN) == 1
    assert "| seattle |" in text and "| aces |" not in text
    assert "40 CPU seconds and 50 s of wall clock" in text and "1 log at a time" in text
    kept = bench.kept_section(page)
    assert kept is not None and kept.startswith(bench.BEGIN) and kept.endswith(bench.END)


def test_without_the_shared_data_it_skips(
    bench: ModuleType,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setattr(bench, "DATA", tmp_path / "absent")
    monkeypatch.setattr(bench, "DOC", tmp_path / "results.md")
    assert bench.jobs_for(None) == []
    bench.main([])
    assert "nothing to measure" in capsys.readouterr().err
    assert not (tmp_path / "results.md").exists()


def test_a_log_name_picks_its_raw_bag_and_its_corrected_log(
    bench: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "slam-benchmark").mkdir()
    (tmp_path / "carmen").mkdir()
    (tmp_path / "slam-benchmark" / "aces.bag").write_bytes(b"")
    (tmp_path / "carmen" / "aces-corrected.log.gz").write_bytes(b"")
    (tmp_path / "carmen" / "seattle-corrected.log.gz").write_bytes(b"")
    monkeypatch.setattr(bench, "DATA", tmp_path)
    assert bench.jobs_for(["aces"]) == [("bag", "aces"), ("carmen", "aces")]
    assert bench.jobs_for(None) == [("bag", "aces"), ("carmen", "aces"), ("carmen", "seattle")]
    with pytest.raises(SystemExit):
        bench.main(["--logs", "nowhere"])
