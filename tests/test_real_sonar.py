"""The seed paper's own sensor on real data: the 8-sonar log of ``../shared/data/sonar``, converted
by samples/udacity_sonar.py and mapped in standard and error-aware mode."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.evaluation.evaluate import load_probability_map
from gridmap_cli.readers import read_log
from gridmap_cli.robot import load_robot
from tests.helpers import run

ROOT = Path(__file__).resolve().parents[1]
SONAR = ROOT.parent / "shared" / "data" / "sonar"

pytestmark = pytest.mark.skipif(not SONAR.is_dir(), reason="../shared/data/sonar is not present")


def _converter():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location(
        "udacity_sonar", ROOT / "samples" / "udacity_sonar.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def converted(tmp_path_factory: pytest.TempPathFactory) -> Path:
    csv_path, _ = _converter().convert(SONAR, tmp_path_factory.mktemp("sonar"))
    return csv_path


def test_the_conversion_keeps_every_sample_in_si_units(converted: Path) -> None:
    raw = np.loadtxt(SONAR / "poses.txt")
    log = read_log(converted)
    assert len(log.poses) == len(raw)
    # millimetres to metres, tenths of a degree to radians wrapped into (-pi, pi]
    k = int(np.argmax(np.abs(raw[:, 1])))
    assert log.poses.x_m[k] == pytest.approx(raw[k, 1] / 1000, abs=1e-3)
    heading = np.radians(raw[:, 3] / 10)
    wrapped = np.angle(np.exp(1j * (log.poses.theta_rad - heading)))
    assert np.max(np.abs(wrapped)) < 1e-5
    assert np.all(np.abs(log.poses.theta_rad) <= math.pi)


def test_the_robot_file_is_the_front_ring_with_the_logs_range_limit(converted: Path) -> None:
    robot = load_robot(str(converted.with_name("sonar-robot.yaml")))
    assert robot.names() == tuple(f"sonar{k}" for k in range(7, -1, -1))
    yaws = [math.degrees(s.yaw_rad) for s in robot.sensors]
    assert yaws == sorted(yaws) and yaws[0] == pytest.approx(-90) and yaws[-1] == pytest.approx(90)
    assert {s.max_range_m for s in robot.sensors} == {5.11}


def test_standard_and_error_aware_maps_of_the_real_log(converted: Path, tmp_path: Path) -> None:
    maps = {}
    for name, extra in (("standard", ()), ("error-aware", _converter().ERROR_AWARE_ARGS)):
        out = tmp_path / f"{name}.png"
        code, stdout, _ = run(
            "build", str(converted), "-o", str(out), "--map-mode", "scale", "--json", *extra
        )
        assert code == 0
        summary = json.loads(stdout)
        # every reading lies in the odometry's span: the two files share their stamps
        assert summary["readings"]["used"] == 3304
        maps[name] = load_probability_map(out.with_suffix(".yaml"))
    standard, aware = maps["standard"], maps["error-aware"]
    known = np.isfinite(standard.prob)
    # the L-shaped run covers tens of metres in both directions
    assert standard.prob.shape[0] * standard.spec.resolution_m > 12
    assert standard.prob.shape[1] * standard.spec.resolution_m > 12
    assert np.count_nonzero(standard.prob[known] >= 0.65) > 100
    # the spread grows along the path: the error-aware map decides fewer cells as walls
    aware_walls = np.count_nonzero(np.nan_to_num(aware.prob, nan=0.5) >= 0.65)
    assert aware_walls < np.count_nonzero(standard.prob[known] >= 0.65)
