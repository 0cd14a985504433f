"""The automatic pose choice (``--pose auto``, the default): the pose graph where the log has a
laser, the odometry otherwise, and a fallback with a warning when the graph fails its checks."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gridmap_cli.poses import sources
from tests.helpers import run, simulated_laser_log

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


@pytest.fixture(scope="module")
def laser_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulated_laser_log(tmp_path_factory.mktemp("auto"))


def _build(log: Path, out: Path, *args: str) -> tuple[int, dict[str, object], str]:
    code, stdout, stderr = run("build", str(log), "-o", str(out), "--json", *args)
    return code, (json.loads(stdout) if code == 0 else {}), stderr


def test_a_sonar_log_is_mapped_with_its_odometry(tmp_path: Path) -> None:
    code, summary, _ = _build(SAMPLES / "corridor_loop.csv", tmp_path / "auto.png")
    assert code == 0
    assert summary["pose_choice"] == {"source": "odometry", "because": "no laser"}
    code, _, _ = _build(SAMPLES / "corridor_loop.csv", tmp_path / "odo.png", "--pose", "odometry")
    assert (tmp_path / "auto.png").read_bytes() == (tmp_path / "odo.png").read_bytes()


def test_a_laser_log_is_mapped_with_the_pose_graph(laser_log: Path, tmp_path: Path) -> None:
    code, summary, stderr = _build(laser_log, tmp_path / "auto.png")
    assert code == 0, stderr
    assert summary["pose_choice"]["source"] == "slam"  # type: ignore[index]
    assert "slam" in summary
    code, _, _ = _build(laser_log, tmp_path / "slam.png", "--pose", "slam")
    assert (tmp_path / "auto.png").read_bytes() == (tmp_path / "slam.png").read_bytes()
    assert "poses: slam (the automatic choice" in stderr


def test_an_odometry_error_model_means_the_odometry(laser_log: Path, tmp_path: Path) -> None:
    args = ("--mode", "error-aware", "--odometry-coefficient", "range_m_per_sqrt_m=0.01")
    code, summary, stderr = _build(laser_log, tmp_path / "auto.png", *args)
    assert code == 0, stderr
    assert summary["pose_choice"]["source"] == "odometry"  # type: ignore[index]


def test_a_graph_that_fails_its_check_falls_back_with_a_warning(
    laser_log: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the graph now fails the check the automatic choice acts on
    monkeypatch.setattr(sources, "graph_failure", lambda result: "forced for the test")
    code, summary, stderr = _build(laser_log, tmp_path / "auto.png")
    assert code == 0, stderr
    chosen = summary["pose_choice"]["source"]  # type: ignore[index]
    assert chosen in ("scan-matched", "odometry")
    assert "--pose auto: the pose graph failed its own check" in stderr
    assert f"mapped with the {chosen} track instead" in stderr
    # trajectory writes the fallback's track and gives the same warning
    code, _, stderr = run("trajectory", str(laser_log), "-o", str(tmp_path / "t.csv"))
    assert code == 0, stderr
    assert "Warning: --pose auto: the pose graph failed its own check" in stderr
    # --pose slam maps with the graph whatever its check says: not the fallback's map
    code, _, stderr = _build(laser_log, tmp_path / "slam.png", "--pose", "slam")
    assert code == 0
    assert (tmp_path / "auto.png").read_bytes() != (tmp_path / "slam.png").read_bytes()


def test_error_aware_sonar_without_a_model_is_a_usage_error(tmp_path: Path) -> None:
    out = tmp_path / "m.png"
    code, _, stderr = run("build", str(SAMPLES / "corridor_loop.csv"), "-o", str(out),
                          "--mode", "error-aware")  # fmt: skip
    assert code == 2
    assert "needs the odometry error" in stderr and "mapped with the odometry track" in stderr
    assert list(tmp_path.iterdir()) == []


def test_a_bend_is_warned_of_but_keeps_the_graph(
    laser_log: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from gridmap_cli.poses.correction import slam

    monkeypatch.setattr(slam, "BEND_WARN_SIGMA", -1.0)  # every closure now "bends" the track
    code, summary, stderr = _build(laser_log, tmp_path / "auto.png")
    assert code == 0, stderr
    assert summary["pose_choice"]["source"] == "slam"  # type: ignore[index]
    assert "a closure may be false" in stderr
