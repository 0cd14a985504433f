"""``gridmap batch``: one map per log, up-to-date maps skipped, failures reported and passed,
a JSON-lines report, one run per output folder at a time."""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

import pytest

from gridmap_cli.errors import GridmapError, UsageError
from gridmap_cli.runs.batch import (
    LOCK_NAME,
    OVERVIEW_NAME,
    REPORT_NAME,
    BatchLock,
    BatchOptions,
    Job,
    JobResult,
    find_logs,
    plan_jobs,
    run_job,
)
from tests.helpers import names, run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


@pytest.fixture
def logs(tmp_path: Path) -> Path:
    """A folder of sample logs and one corrupt MCAP (a zstd chunk with a flipped byte)."""
    folder = tmp_path / "logs"
    folder.mkdir()
    for name in ("corridor_loop.csv", "corridor_loop.2d", "hall.csv"):
        shutil.copy(SAMPLES / name, folder / name)
    data = bytearray((SAMPLES / "corridor_loop.mcap").read_bytes())
    data[3000] ^= 0xFF
    (folder / "broken.mcap").write_bytes(bytes(data))
    (folder / "notes.txt").write_text("not a log\n")
    return folder


def report(outdir: Path) -> list[dict[str, object]]:
    lines = (outdir / REPORT_NAME).read_text().splitlines()
    return [json.loads(line) for line in lines]


def test_a_folder_with_one_corrupt_log_writes_every_other_map_the_report_and_exits_1(
    logs: Path, tmp_path: Path
) -> None:
    out = tmp_path / "maps"
    code, stdout, err = run("batch", str(logs), "-o", str(out))
    assert (code, stdout) == (1, "")
    assert names(out) == {
        "corridor_loop-2d.png", "corridor_loop-2d.yaml", ".corridor_loop-2d.batch.json",
        "corridor_loop-csv.png", "corridor_loop-csv.yaml", ".corridor_loop-csv.batch.json",
        "hall.png", "hall.yaml", ".hall.batch.json", REPORT_NAME, LOCK_NAME, OVERVIEW_NAME,
    }  # fmt: skip
    lines = report(out)
    assert [(Path(str(r["log"])).name, r["status"]) for r in lines] == [
        ("broken.mcap", "failed"),
        ("corridor_loop.2d", "built"),
        ("corridor_loop.csv", "built"),
        ("hall.csv", "built"),
    ]
    broken = lines[0]
    assert str(broken["error"]).startswith(f"{logs / 'broken.mcap'}: byte ")
    built = lines[2]
    assert (
        built["map_bytes"]
        == (out / "corridor_loop-csv.png").stat().st_size
        + (out / "corridor_loop-csv.yaml").stat().st_size
    )
    cells = built["cells"]
    assert isinstance(cells, dict) and cells["observed"] > 0 and cells["width"] > 0
    seconds = built["seconds"]
    assert isinstance(seconds, dict) and set(seconds) >= {"read", "map", "write", "total"}
    assert "Failed: " in err and "3 built, 0 up to date, 1 failed of 4 logs" in err
    # the same bytes as gridmap build
    assert run("build", str(logs / "hall.csv"), "-o", str(tmp_path / "h.png"), "-q")[0] == 0
    assert (out / "hall.png").read_bytes() == (tmp_path / "h.png").read_bytes()


def test_up_to_date_maps_are_skipped_and_changes_rebuild(logs: Path, tmp_path: Path) -> None:
    out = tmp_path / "maps"
    (logs / "broken.mcap").unlink()
    assert run("batch", str(logs), "-o", str(out), "-q")[0] == 0
    before = (out / "hall.png").stat().st_mtime_ns
    code, _, err = run("batch", str(logs), "-o", str(out))
    assert code == 0 and "0 built, 3 up to date" in err
    assert {r["status"] for r in report(out)} == {"skipped"}
    assert (out / "hall.png").stat().st_mtime_ns == before
    # a touched but unchanged log is still up to date; a changed one is rebuilt
    (logs / "hall.csv").touch()
    with open(logs / "corridor_loop.csv", "a") as handle:
        handle.write("\n")
    run("batch", str(logs), "-o", str(out), "-q")
    statuses = {Path(str(r["log"])).name: r["status"] for r in report(out)}
    assert statuses == {
        "corridor_loop.2d": "skipped", "corridor_loop.csv": "built", "hall.csv": "skipped"
    }  # fmt: skip
    # another option rebuilds every map
    run("batch", str(logs), "-o", str(out), "-q", "--resolution", "0.1")
    assert {r["status"] for r in report(out)} == {"built"}
    # a map deleted by hand is rebuilt
    (out / "hall.png").unlink()
    run("batch", str(logs), "-o", str(out), "-q", "--resolution", "0.1")
    assert {Path(str(r["log"])).name: r["status"] for r in report(out)}["hall.csv"] == "built"


def test_local_processes_give_the_same_bytes(logs: Path, tmp_path: Path) -> None:
    one, two = tmp_path / "one", tmp_path / "two"
    assert run("batch", str(logs), "-o", str(one), "-q")[0] == 1
    assert run("batch", str(logs), "-o", str(two), "-q", "--jobs", "3")[0] == 1
    for name in ("corridor_loop-2d.png", "corridor_loop-csv.yaml", "hall.png"):
        assert (one / name).read_bytes() == (two / name).read_bytes()
    varying = ("seconds", "map", "log", "built_at")
    strip = [{k: v for k, v in r.items() if k not in varying} for r in report(one)]
    assert strip == [{k: v for k, v in r.items() if k not in varying} for r in report(two)]


def test_a_second_run_on_a_locked_folder_stops_at_once(logs: Path, tmp_path: Path) -> None:
    out = tmp_path / "maps"
    out.mkdir()
    with BatchLock(out):
        code, _, err = run("batch", str(logs), "-o", str(out))
        assert code == 1
        assert err.startswith(f"Error: {out}: another gridmap batch is writing here (pid ")
        assert err.count("\n") == 1
        with pytest.raises(GridmapError), BatchLock(out):
            pass
    assert names(out) == {LOCK_NAME}
    with BatchLock(out):  # released: taken again
        pass


def test_the_lock_of_a_killed_run_is_free(tmp_path: Path) -> None:
    import subprocess

    code = (
        "import os, sys; from pathlib import Path; from gridmap_cli.runs.batch import BatchLock; "
        "lock = BatchLock(Path(sys.argv[1])).__enter__(); os._exit(9)"
    )
    subprocess.run([sys.executable, "-c", code, str(tmp_path)], check=False)
    with BatchLock(tmp_path):
        pass


def test_inputs_files_folders_and_globs(logs: Path, tmp_path: Path) -> None:
    found = find_logs([str(logs / "hall.csv"), str(logs / "corridor_loop.*"), str(logs)])
    assert [p.name for p in found] == [
        "broken.mcap", "corridor_loop.2d", "corridor_loop.csv", "hall.csv"
    ]  # fmt: skip
    assert [p.name for p in find_logs([str(tmp_path / "**" / "*.csv")])] == [
        "corridor_loop.csv", "hall.csv"
    ]  # fmt: skip
    with pytest.raises(UsageError, match="no log there"):
        find_logs([str(tmp_path / "*.bag")])
    code, _, err = run("batch", str(tmp_path / "none*.csv"), "-o", str(tmp_path / "o"))
    assert code == 2 and err.count("\n") == 1 and "no log there" in err


def test_map_names_follow_the_logs(tmp_path: Path) -> None:
    options = BatchOptions()
    jobs = plan_jobs(
        [Path("a/run.mcap"), Path("a/x.log.gz"), Path("a/bag2"), Path("a/y.csv")], tmp_path,
        options,
    )  # fmt: skip
    assert [j.output.name for j in jobs] == ["run.png", "x.png", "bag2.png", "y.png"]
    with pytest.raises(UsageError, match=r"several logs would write run-csv\.png"):
        plan_jobs([Path("a/run.csv"), Path("b/run.csv")], tmp_path, options)


def test_usage_errors_come_before_any_work(logs: Path, tmp_path: Path) -> None:
    out = tmp_path / "o"
    for args, text in [
        (("--resolution", "1e6"), "--resolution"),
        (("--executor", "dask"), "--scheduler ADDRESS"),
        (("--scheduler", "tcp://x:1"), "--executor dask"),
        (("--robot", "nosuchrobot"), "unknown robot"),
        (("--executor", "dask", "--scheduler", "not an address"), "not a Dask scheduler address"),
        (("--executor", "dask", "--scheduler", "tcp://host"), "not a Dask scheduler address"),
        (("--executor", "dask", "--scheduler", "ftp://host:21"), "not a Dask scheduler address"),
    ]:
        code, _, err = run("batch", str(logs), "-o", str(out), *args)
        assert code == 2 and err.count("\n") == 1 and text in err, err
    assert not out.exists()


def test_dask_without_the_extra_says_how_to_install(
    logs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    code, _, err = run("batch", str(logs), "-o", str(tmp_path / "o"), "--executor", "dask",
                       "--scheduler", "tcp://127.0.0.1:1")  # fmt: skip
    assert code == 2
    assert err.strip() == (
        "Error: --executor dask needs the Dask extra, which is not installed: "
        "pip install 'gridmap-cli[dask]'"
    )


def _dies_on_hall(job: Job) -> JobResult:
    """run_job, except that the process building hall.csv dies as the OOM killer ends one."""
    if job.log.name == "hall.csv":
        os._exit(9)
    return run_job(job)


def test_a_worker_that_dies_fails_its_log_and_the_batch_goes_on(
    logs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(
        "gridmap_cli.runs.batch.run_job", _dies_on_hall
    )  # executors look it up there
    out = tmp_path / "maps"
    code, _, _ = run("batch", str(logs / "hall.csv"), str(logs / "corridor_loop.csv"),
                     "-o", str(out), "--jobs", "2")  # fmt: skip
    assert code == 1
    statuses = {Path(str(r["log"])).name: (r["status"], str(r["error"])) for r in report(out)}
    assert statuses["hall.csv"][0] == "failed"
    assert "the worker building it died (BrokenProcessPool" in statuses["hall.csv"][1]
    # the pool broke with that worker: the other log was built before, or failed with it
    assert statuses["corridor_loop.csv"][0] in ("built", "failed")


def test_two_logs_with_one_name_are_refused_in_one_line_and_leave_nothing(
    logs: Path, tmp_path: Path
) -> None:
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(SAMPLES / "office.csv", other / "hall.csv")  # another file, the same name
    out = tmp_path / "maps"
    code, _, err = run("batch", str(logs / "hall.csv"), str(other / "hall.csv"), "-o", str(out))
    assert code == 2 and err.count("\n") == 1
    assert err.startswith(
        f"Error: several logs would write hall-csv.png: {logs / 'hall.csv'} and "
        f"{other / 'hall.csv'} (the same name"
    )
    assert not out.exists()
    # into an existing folder: nothing added to it, no lock
    out.mkdir()
    assert run("batch", str(logs / "hall.csv"), str(other / "hall.csv"), "-o", str(out))[0] == 2
    assert names(out) == set()


def test_a_report_in_a_missing_folder_is_refused_before_any_map(logs: Path, tmp_path: Path) -> None:
    out = tmp_path / "maps"
    code, _, err = run("batch", str(logs / "hall.csv"), "-o", str(out),
                       "--report", str(tmp_path / "nowhere" / "r.jsonl"))  # fmt: skip
    assert code == 1 and err.count("\n") == 1 and "does not exist" in err
    assert not out.exists()


def test_a_file_reached_twice_through_a_symlink_loop_is_one_log(logs: Path, tmp_path: Path) -> None:
    (logs / "broken.mcap").unlink()
    (logs / "loop").symlink_to(logs, target_is_directory=True)  # logs/loop/loop/... is logs
    (logs / "again.csv").symlink_to(logs / "hall.csv")  # a link beside its target
    found = find_logs([str(logs / "**" / "*.csv"), str(logs / "hall.csv")])
    assert [p.name for p in found] == ["corridor_loop.csv", "hall.csv"]
    assert all(p == p.resolve() for p in found)
    out = tmp_path / "maps"
    code, _, err = run("batch", str(logs / "**" / "*.csv"), "-o", str(out))
    assert code == 0, err
    assert "2 built, 0 up to date, 0 failed of 2 logs" in err
    assert [Path(str(r["log"])).name for r in report(out)] == ["corridor_loop.csv", "hall.csv"]
