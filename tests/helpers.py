"""Helpers shared by the tests: running the CLI in-process, tiny logs built inline."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import numpy as np
from click.testing import CliRunner

from gridmap_cli.cli import cli
from gridmap_cli.records import PoseTrack, RangeLog, RangeReadings


def run(*args: str) -> tuple[int, str, str]:
    """Run ``gridmap ARGS`` in-process: exit code, stdout, stderr.

    An unexpected exception (not click's SystemExit) is re-raised, so that a crash shows its
    traceback instead of passing as a non-zero exit.
    """
    result = CliRunner().invoke(cli, list(args))
    if result.exception and not isinstance(result.exception, SystemExit):
        raise result.exception
    return result.exit_code, result.stdout, result.stderr


def built(tmp_path: Path, name: str, *args: str) -> tuple[bytes, bytes]:
    """``gridmap build ARGS`` into ``tmp_path/name/map.png`` (one file name for every build,
    as the YAML names its image): the PNG and YAML bytes, for byte-for-byte comparisons."""
    (tmp_path / name).mkdir()
    out = tmp_path / name / "map.png"
    code, _, stderr = run("build", *args, "-o", str(out), "-q")
    assert code == 0, stderr
    return out.read_bytes(), out.with_suffix(".yaml").read_bytes()


def names(folder: Path) -> set[str]:
    """Names of the entries of ``folder``: what a command left behind."""
    return {p.name for p in folder.iterdir()}


def log_with_truth(
    truth: list[tuple[float, float, float]], odometry: list[tuple[float, float, float]]
) -> RangeLog:
    """A p3dx log at 10 Hz: the given true and odometry poses, one 2 m sonar0 reading per pose.

    Poses are (x_m, y_m, theta_rad); both lists have one entry per stamp.
    """
    n = len(truth)
    stamps = np.arange(n, dtype=np.int64) * 100_000_000
    return RangeLog(
        source="test",
        poses=PoseTrack.from_rows(stamps, odometry),
        readings=RangeReadings(stamps.copy(), np.zeros(n, np.int32), np.full(n, 2.0)),
        sensor_names=("sonar0",),
        truth=PoseTrack.from_rows(stamps, truth),
        metadata={"robot": "p3dx"},
    )


def simulated_laser_log(folder: Path) -> Path:
    """A minute of the office world's laser robot whose odometry drifts: loops the pose graph
    closes (the log the automatic pose choice and the free-space check are tried on)."""
    samples = Path(__file__).resolve().parents[1] / "samples"
    log = folder / "laser.2d"
    code, _, stderr = run(
        "simulate", str(samples / "worlds" / "office.yaml"), str(samples / "paths" / "office.yaml"),
        "--robot", "p3at-lms200", "--duration", "60", "--drift", "2", "-o", str(log),
    )  # fmt: skip
    assert code == 0, stderr
    return log


def bench_script(name: str, *imports: str) -> Iterator[ModuleType]:
    """``bench/NAME.py`` loaded as module ``name`` for a fixture's span (``bench/`` is not a
    package); on the way out it and ``imports``, the benches it imported, leave
    ``sys.modules``."""
    script = Path(__file__).resolve().parents[1] / "bench" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, script)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        for loaded in (name, *imports):
            sys.modules.pop(loaded, None)
