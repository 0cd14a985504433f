"""`gridmap build --jobs N`: the same map, to the byte, for every N."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gridmap_cli import extensions
from gridmap_cli.mapping import pipeline, shards
from gridmap_cli.mapping.grid import LogOddsAccumulator
from gridmap_cli.mapping.pipeline import BuildOptions, plan_build
from gridmap_cli.poses.sync import select_readings
from gridmap_cli.readers import read_log
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.robot import load_robot
from tests.helpers import run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
LOG = SAMPLES / "corridor_loop.csv"


def built(tmp_path: Path, log: Path, name: str, *extra: str) -> tuple[bytes, bytes]:
    (tmp_path / name).mkdir()
    out = tmp_path / name / "map.png"  # one name: the YAML names its image
    code, _, stderr = run("build", str(log), "-o", str(out), "-q", "--map-mode", "scale", *extra)
    assert code == 0, stderr
    return out.read_bytes(), out.with_suffix(".yaml").read_bytes()


def test_jobs_give_the_map_of_one_job_byte_for_byte(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # small shards, so that the sample log is many of them and the workers share them unevenly
    monkeypatch.setattr(shards, "SHARD_READINGS", 3_000)
    one = built(tmp_path, LOG, "one", "--jobs", "1")
    for jobs in ("2", "3"):
        assert built(tmp_path, LOG, f"j{jobs}", "--jobs", jobs) == one


@pytest.mark.parametrize("kernels", ["compiled", "numpy"])
def test_error_aware_jobs_give_the_map_of_one_job_byte_for_byte(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, kernels: str
) -> None:
    # both error-aware maps (sampled tracks, analytic fade) are log-odds shards, on either kernels
    monkeypatch.setattr(extensions, "KERNELS", kernels)
    log = tmp_path / "laser.2d"
    code, _, stderr = run(
        "simulate", str(SAMPLES / "worlds" / "office.yaml"), str(SAMPLES / "paths" / "office.yaml"),
        "--robot", "p3at-lms200", "--duration", "3", "-o", str(log),
    )  # fmt: skip
    assert code == 0, stderr
    flags = ("--robot", "p3at-lms200", "--mode", "error-aware",
             "--odometry-coefficient", "range_m_per_m=0.01")  # fmt: skip
    one = built(tmp_path, log, "one", *flags, "--jobs", "1")
    assert built(tmp_path, log, "two", *flags, "--jobs", "2") == one
    fade = (*flags, "--error-samples", "0")
    faded = built(tmp_path, log, "faded", *fade, "--jobs", "1")
    assert faded != one
    assert built(tmp_path, log, "faded2", *fade, "--jobs", "2") == faded


def test_a_log_of_one_shard_maps_as_one_grid_batch_by_batch() -> None:
    robot = load_robot("p3at")
    log = read_log(LOG, None, ReadOptions(robot=robot))
    options = BuildOptions(batch_size=2_000)
    plan = plan_build(log, robot, options)
    assert plan.sync.used < shards.SHARD_READINGS
    sharded = LogOddsAccumulator(plan.spec)
    pipeline.accumulate(plan, sharded, options)
    direct = LogOddsAccumulator(plan.spec)
    for model, part in plan.parts():
        for start, stop in shards.batch_bounds(part.stamp_ns, options.batch_size):
            model.accumulate(direct, select_readings(part, slice(start, stop)))
    assert np.array_equal(sharded.log_odds(), direct.log_odds())
    assert np.array_equal(sharded.observations(), direct.observations())


def test_results_come_back_in_the_order_of_the_tasks() -> None:
    tasks = [(2, k) for k in range(12)]
    assert list(shards.in_order(pow, tasks, 3)) == [2**k for k in range(12)]
    assert list(shards.in_order(pow, tasks, 1)) == [2**k for k in range(12)]


def test_a_log_synchronised_in_chunks_maps_as_in_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    whole = built(tmp_path, LOG, "whole")
    # chunks of a few scans: bounds and sync counts are gathered over many, the shards follow them
    monkeypatch.setattr(pipeline, "SYNC_CHUNK_READINGS", 700)
    assert built(tmp_path, LOG, "chunked") == whole
    robot = load_robot("p3at")
    log = read_log(LOG, None, ReadOptions(robot=robot))
    chunked = plan_build(log, robot, BuildOptions())
    monkeypatch.setattr(pipeline, "SYNC_CHUNK_READINGS", 10**9)
    one = plan_build(log, robot, BuildOptions())
    assert len(chunked.chunks) > 10
    assert (chunked.sync, chunked.spec) == (one.sync, one.spec)
