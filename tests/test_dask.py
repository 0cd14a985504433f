"""Batch and fused builds on a real Dask cluster (``distributed.LocalCluster``, two worker
processes, no mocks): the same bytes as the local executor.

``distributed`` is the ``dask`` extra (the dev extra installs it). Without it the tests skip,
except under CI (the CI variable set), where a missing install must fail, not pass unseen.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

from gridmap_cli.runs.batch import REPORT_NAME
from tests.helpers import run

try:
    from distributed import LocalCluster
except ImportError:  # pragma: no cover - only without the extra
    if os.environ.get("CI"):
        raise
    pytest.skip("distributed (the dask extra) is not installed", allow_module_level=True)

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


@pytest.fixture(scope="module")
def scheduler() -> Iterator[str]:
    cluster = LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
        scheduler_port=0,
    )  # fmt: skip
    try:
        yield str(cluster.scheduler_address)
    finally:
        cluster.close()


@pytest.fixture
def logs(tmp_path: Path) -> Path:
    folder = tmp_path / "logs"
    folder.mkdir()
    for name in ("corridor_loop.csv", "corridor_loop.2d", "hall.csv"):
        shutil.copy(SAMPLES / name, folder / name)
    (folder / "broken.csv").write_text("time,x,y,theta,sonar0\n0,0,0,0,1\n0,0,0\n")
    return folder


def test_batch_on_dask_writes_the_same_bytes_as_local(
    scheduler: str, logs: Path, tmp_path: Path
) -> None:
    local, dask = tmp_path / "local", tmp_path / "dask"
    assert run("batch", str(logs), "-o", str(local), "-q", "--jobs", "2")[0] == 1
    code, _, err = run("batch", str(logs), "-o", str(dask), "--executor", "dask",
                       "--scheduler", scheduler)  # fmt: skip
    assert code == 1, err
    assert "3 built, 0 up to date, 1 failed of 4 logs" in err
    names = sorted(p.name for p in local.iterdir() if p.suffix in (".png", ".yaml"))
    assert len(names) == 6
    for name in names:
        assert (local / name).read_bytes() == (dask / name).read_bytes(), name
    lines = (dask / REPORT_NAME).read_text().splitlines()
    assert len(lines) == 4 and '"status": "failed"' in lines[0]
    # a second run on the cluster finds every map up to date
    code, _, err = run("batch", str(logs), "-o", str(dask), "--executor", "dask",
                       "--scheduler", scheduler)  # fmt: skip
    assert "0 built, 3 up to date, 1 failed" in err


def test_a_fused_build_reduced_on_dask_is_the_local_bytes(scheduler: str, tmp_path: Path) -> None:
    logs = [str(SAMPLES / n) for n in ("corridor_loop.csv", "hall.csv", "office.csv")]
    local, dask = tmp_path / "local.png", tmp_path / "dask.png"
    code, _, err = run("build", *logs, "-o", str(local), "--fuse", "--pose", "global", "-q")
    assert code == 0, err
    code, _, err = run("build", *reversed(logs), "-o", str(dask), "--fuse", "--pose", "global",
                       "-q", "--executor", "dask", "--scheduler", scheduler)  # fmt: skip
    assert code == 0, err
    assert local.read_bytes() == dask.read_bytes()
    yaml_local = local.with_suffix(".yaml").read_text().replace("local.png", "dask.png")
    assert yaml_local == dask.with_suffix(".yaml").read_text()


def test_an_unreachable_scheduler_is_one_line(
    tmp_path: Path, logs: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("gridmap_cli.runs.executors.DASK_CONNECT_TIMEOUT", "1s")
    code, _, err = run("batch", str(logs), "-o", str(tmp_path / "o"), "--executor", "dask",
                       "--scheduler", "tcp://127.0.0.1:9")  # fmt: skip
    assert code == 1 and err.count("\n") == 1
    assert err.startswith("Error: cannot reach the Dask scheduler at tcp://127.0.0.1:9")
    assert not (tmp_path / "o").exists()  # refused before the folder (and its lock) exist
