"""Ctrl-C during ``gridmap batch``: exit 130, one line naming what finished, the finished logs'
report lines and the overview kept, the other maps left as they were, no worker left behind."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gridmap_cli.runs.batch import LOCK_NAME, OVERVIEW_NAME, REPORT_NAME, Job, JobResult, run_job
from tests.helpers import names, run

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"
#: A bound that catches a hang, not a slow machine: nothing waits on it unless something hangs.
HANG_S = 600.0


@pytest.fixture
def logs(tmp_path: Path) -> Path:
    folder = tmp_path / "logs"
    folder.mkdir()
    for name in ("a", "b", "c", "d"):
        shutil.copy(SAMPLES / "hall.csv", folder / f"{name}.csv")
    return folder


def interrupted_at_c(job: Job) -> JobResult:
    """run_job, except that Ctrl-C comes while c.csv is built."""
    if job.log.name == "c.csv":
        raise KeyboardInterrupt
    return run_job(job)


def stuck_on_c_and_d(job: Job) -> JobResult:
    """run_job, except that c.csv and d.csv never finish (say so with a file beside the log,
    then wait until stopped), so however slow the machine, only Ctrl-C ends them."""
    if job.log.stem in ("c", "d"):
        job.log.with_suffix(".started").touch()
        while True:
            time.sleep(0.05)
    return run_job(job)


def report(outdir: Path) -> list[dict[str, object]]:
    return [json.loads(line) for line in (outdir / REPORT_NAME).read_text().splitlines()]


def test_ctrl_c_keeps_the_finished_logs_report_and_says_what_finished(
    logs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("gridmap_cli.runs.batch.run_job", interrupted_at_c)
    out = tmp_path / "maps"
    code, _, err = run("batch", str(logs), "-o", str(out))
    assert code == 130
    assert err.count("\n") == 1
    assert err.startswith(
        "Error: interrupted (Ctrl-C); 2 of 4 logs finished: 2 built (a.png, b.png), 0 up to "
        "date, 0 failed; the other 2 maps were left as they were; report "
        f"{out / REPORT_NAME}, overview {out / OVERVIEW_NAME}"
    )
    assert [(Path(str(r["log"])).name, r["status"]) for r in report(out)] == [
        ("a.csv", "built"), ("b.csv", "built")
    ]  # fmt: skip
    assert names(out) == {
        "a.png", "a.yaml", ".a.batch.json", "b.png", "b.yaml", ".b.batch.json",
        REPORT_NAME, OVERVIEW_NAME, LOCK_NAME,
    }  # fmt: skip
    page = (out / OVERVIEW_NAME).read_text()
    assert "Interrupted (Ctrl-C) after 2 of 4 logs" in page
    assert "Not finished (2)" in page and str(logs / "d.csv") in page
    # the next run builds what the interrupted one did not, and keeps what it did
    monkeypatch.undo()
    code, _, err = run("batch", str(logs), "-o", str(out))
    assert code == 0 and "2 built, 2 up to date, 0 failed of 4 logs" in err


def _start_batch(logs: Path, out: Path) -> subprocess.Popen[str]:
    """``gridmap batch --jobs 2`` in its own process group, c.csv and d.csv stuck."""
    code = (
        "import sys; from gridmap_cli.runs import batch; "
        "from tests.test_batch_interrupt import stuck_on_c_and_d; "
        "batch.run_job = stuck_on_c_and_d; from gridmap_cli.cli import main; "
        "sys.argv = ['gridmap', 'batch', sys.argv[1], '-o', sys.argv[2], '--jobs', '2']; main()"
    )
    return subprocess.Popen(
        [sys.executable, "-c", code, str(logs), str(out)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


@pytest.mark.parametrize("to", ["terminal", "main process"])
def test_ctrl_c_stops_local_workers_and_leaves_no_process(
    logs: Path, tmp_path: Path, to: str
) -> None:
    """A terminal's Ctrl-C reaches every process of the group; ``kill -INT`` the main one
    alone: either way the stuck workers are stopped, and the run ends with exit 130."""
    out = tmp_path / "maps"
    proc = _start_batch(logs, out)
    try:
        deadline = time.monotonic() + HANG_S
        started = [logs / "c.started", logs / "d.started"]
        while not all(p.exists() for p in started) and time.monotonic() < deadline:
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.05)
        assert all(p.exists() for p in started)
        if to == "terminal":
            os.killpg(proc.pid, signal.SIGINT)
        else:
            os.kill(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=HANG_S)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(
        "Error: interrupted (Ctrl-C); 2 of 4 logs finished: 2 built (a.png, b.png)"
    ), err
    assert [Path(str(r["log"])).name for r in report(out)] == ["a.csv", "b.csv"]
    assert names(out) == {
        "a.png", "a.yaml", ".a.batch.json", "b.png", "b.yaml", ".b.batch.json",
        REPORT_NAME, OVERVIEW_NAME, LOCK_NAME,
    }  # fmt: skip
    with pytest.raises(ProcessLookupError):  # no worker of the group is left running
        for _ in range(int(HANG_S / 0.1)):
            os.killpg(proc.pid, 0)
            time.sleep(0.1)
