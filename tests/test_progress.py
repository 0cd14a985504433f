"""Progress on a terminal for every slow stage (reading, scan matching, loop closures, mapping),
and nothing when stderr is not a terminal (pipelines, cron) or with --quiet."""

from __future__ import annotations

import io
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from gridmap_cli.cli import progress
from gridmap_cli.writers.csv_log import save_csv_log
from tests.helpers import run
from tests.test_scan_match import room_world
from tests.test_scan_match import run as simulate_run


class FakeTerminal(io.StringIO):
    """What tqdm writes to, claiming to be a terminal."""

    def isatty(self) -> bool:
        return True


@pytest.fixture
def terminal(monkeypatch: pytest.MonkeyPatch) -> FakeTerminal:
    """The progress module's stderr as a terminal, and its bars drawn at once."""
    screen = FakeTerminal()
    monkeypatch.setattr(progress, "sys", SimpleNamespace(stderr=screen))
    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)
    monkeypatch.setattr(progress, "TICK_S", 0.01)
    return screen


def test_stage_bars_draw_one_bar_per_stage_on_a_terminal(terminal: FakeTerminal) -> None:
    with progress.StageBars(quiet=False) as bars:
        for k in range(1, 4):
            bars("scan matching", k, 3)
        bars("loop closures", 0, 5)
        bars("loop closures", 5, 5)
    text = terminal.getvalue()
    assert "scan matching:" in text and "/3 " in text and " scans" in text
    assert "loop closures:" in text and "/5 " in text and " rounds" in text


@pytest.mark.parametrize("quiet", [False, True])
def test_stage_bars_draw_nothing_off_a_terminal_or_when_quiet(
    monkeypatch: pytest.MonkeyPatch, quiet: bool
) -> None:
    screen = FakeTerminal() if quiet else io.StringIO()
    monkeypatch.setattr(progress, "sys", SimpleNamespace(stderr=screen))
    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)
    with progress.StageBars(quiet=quiet) as bars:
        bars("scan matching", 1, 2)
        bars("scan matching", 2, 2)
    with progress.reading("run.log", quiet=quiet):
        time.sleep(0.05)
    assert screen.getvalue() == ""


def test_reading_shows_how_long_it_has_been_reading(terminal: FakeTerminal) -> None:
    with progress.reading("run.log", quiet=False):
        time.sleep(0.1)
    assert "reading run.log: 00:00" in terminal.getvalue()


def _laser_log(tmp_path: Path) -> Path:
    log = simulate_run(room_world(), [[2, 1.5], [10, 1.5]], drift=1.0)
    csv = tmp_path / "run.csv"
    save_csv_log(log, csv)
    return csv


def test_build_scan_matched_reports_reading_and_matching_on_a_terminal(
    tmp_path: Path, terminal: FakeTerminal
) -> None:
    log = _laser_log(tmp_path)
    out = tmp_path / "map.png"
    code, _, stderr = run(
        "build", str(log), "-o", str(out), "--pose", "scan-matched", "--robot", "p3at-lms200"
    )
    assert code == 0, stderr
    text = terminal.getvalue()
    assert "reading run.csv" in text
    assert "scan matching" in text and " scans" in text


def test_build_scan_matched_off_a_terminal_writes_no_bar(tmp_path: Path) -> None:
    log = _laser_log(tmp_path)
    out = tmp_path / "map.png"
    code, _, stderr = run(
        "build", str(log), "-o", str(out), "--pose", "scan-matched", "--robot", "p3at-lms200"
    )
    assert code == 0, stderr
    # the summary line only: no bar, no carriage returns
    assert stderr.count("\n") == 1 and stderr.startswith("gridmap: ")
    assert "\r" not in stderr and "scan matching" not in stderr


def test_trajectory_and_calibrate_report_scan_matching_on_a_terminal(
    tmp_path: Path, terminal: FakeTerminal
) -> None:
    log = _laser_log(tmp_path)
    code, _, stderr = run(
        "trajectory", str(log), "-o", str(tmp_path / "t.tum"), "--robot", "p3at-lms200",
        "--pose", "scan-matched",
    )  # fmt: skip
    assert code == 0, stderr
    assert "scan matching" in terminal.getvalue()
    terminal.truncate(0)
    code, _, stderr = run("calibrate", str(log), "--pose", "scan-matched", "--robot", "p3at-lms200")
    assert code == 0, stderr
    assert "reading run.csv" in terminal.getvalue() and "scan matching" in terminal.getvalue()
