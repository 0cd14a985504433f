"""The Python API: docs/python-api.md's example runs, errors name arguments, the registry of pose
sources is the one place a source is added."""

from __future__ import annotations

import dataclasses
import re
import shutil
import subprocess
import sys
from pathlib import Path

import click
import numpy as np
import pytest

import gridmap_cli as gridmap
from gridmap_cli.poses import sources
from gridmap_cli.poses.sources import SOURCES, PosedLog, PoseSettings, PoseSource, source_names
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RobotDescription
from tests.helpers import run

REPO = Path(__file__).resolve().parent.parent
SAMPLES = REPO / "samples"
CSV = SAMPLES / "corridor_loop.csv"


def _example() -> str:
    text = (REPO / "docs" / "python-api.md").read_text(encoding="utf-8")
    blocks = re.findall(r"^```python\n(.*?)^```", text, re.S | re.M)
    assert len(blocks) == 1
    return str(blocks[0])


def test_the_docs_example_builds_the_map_the_command_line_builds(tmp_path: Path) -> None:
    (tmp_path / "samples").mkdir()
    shutil.copy(CSV, tmp_path / "samples" / CSV.name)
    done = subprocess.run(
        [sys.executable, "-c", _example()], cwd=tmp_path, capture_output=True, text=True,
        env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert re.search(r"^\d+ x \d+ cells, \d+% unknown$", done.stdout, re.M)
    assert re.search(r"^\d+ poses, the last at x=-?\d+\.\d\d m", done.stdout, re.M)
    cli_map = tmp_path / "cli.pgm"
    code, _, err = run("build", str(CSV), "-o", str(cli_map), "--resolution", "0.1", "-q")
    assert code == 0, err
    assert (tmp_path / "out" / "corridor.pgm").read_bytes() == cli_map.read_bytes()
    assert (tmp_path / "out" / "corridor.yaml").is_file()


def test_import_is_cheap_and_every_exported_name_resolves() -> None:
    probe = "import sys, gridmap_cli; print(' '.join(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, cwd=REPO).stdout.split()  # fmt: skip
    assert "numpy" not in out and not [m for m in out if m.startswith("gridmap_cli.")]
    for name in gridmap.__all__:
        assert getattr(gridmap, name) is not None
    with pytest.raises(AttributeError):
        _ = gridmap.no_such_name


def test_errors_name_arguments_not_flags() -> None:
    log = gridmap.read_log(CSV)
    with pytest.raises(gridmap.GridmapError) as bad:
        gridmap.MapOptions(resolution=-1.0).request(log=log)
    assert str(bad.value) == "resolution must be a positive number of metres, got -1.0"
    request = gridmap.MapOptions(pose="scan-matched").request(log=log)
    with pytest.raises(gridmap.GridmapError) as no_laser:
        gridmap.build(request)
    assert str(no_laser.value).endswith(
        "pose='scan-matched' matches laser scans, and the log has no laser (its range sensors: "
        "sonar); use pose='odometry' or pose='global'"
    )
    assert "--" not in str(no_laser.value)


def test_an_existing_map_is_kept_unless_force_is_given(tmp_path: Path) -> None:
    built = gridmap.build(gridmap.MapOptions(resolution=0.2).request(inputs=CSV))
    image, _ = gridmap.write_map(tmp_path / "m.pgm", built.map)
    first = image.read_bytes()
    wider = gridmap.build(gridmap.MapOptions(resolution=0.4).request(inputs=CSV))
    with pytest.raises(gridmap.GridmapError) as exists:
        gridmap.write_map(tmp_path / "m.pgm", wider.map)
    assert str(exists.value) == f"{tmp_path / 'm.pgm'} exists (use force=True to overwrite)"
    assert image.read_bytes() == first
    gridmap.write_map(tmp_path / "m.pgm", wider.map, force=True)
    assert image.read_bytes() != first


def test_the_logs_robot_line_is_applied(tmp_path: Path) -> None:
    text = CSV.read_text(encoding="utf-8")
    plain = tmp_path / "plain.csv"
    plain.write_text(text.replace("# robot: p3at\n", ""), encoding="utf-8")
    with pytest.raises(gridmap.GridmapError, match=r"; give robot \(a preset name"):
        gridmap.build(gridmap.MapOptions().request(inputs=plain))
    named = gridmap.build(gridmap.MapOptions().request(inputs=CSV))
    given = gridmap.build(gridmap.MapOptions(robot="p3at").request(inputs=plain))
    assert np.array_equal(named.map.prob, given.map.prob, equal_nan=True)


def test_a_built_map_gives_its_spread_layer_and_quality() -> None:
    log = gridmap.read_log(CSV)
    plain = gridmap.build(gridmap.MapOptions(resolution=0.2).request(log=log))
    assert plain.spread() is None
    aware = gridmap.MapOptions(resolution=0.2, mode="error-aware", error_samples=2,
                               odometry_coefficients=("range_m_per_m=0.05",))  # fmt: skip
    built = gridmap.build(aware.request(log=log))
    spread = built.spread()
    assert spread is not None
    layer, _ = spread
    assert layer.shape == built.map.prob.shape
    assert np.array_equal(np.isnan(layer), np.isnan(built.map.prob))
    quality = built.quality((0.65, 0.25), spread).as_dict()
    assert quality["spread"]["known_cells"] == int(np.count_nonzero(~np.isnan(layer)))
    assert quality["echo_consistency"] is None  # a sonar log: no laser echo is counted


def shifted_poses(log: RangeLog, robot: RobotDescription | None, _: PoseSettings) -> PosedLog:
    """A pose source for the test below: the odometry moved 1 m along x."""
    poses = dataclasses.replace(log.poses, x_m=log.poses.x_m + 1.0)
    return PosedLog(dataclasses.replace(log, poses=poses), "shifted")


def test_a_new_pose_source_is_one_registration(monkeypatch: pytest.MonkeyPatch) -> None:
    shifted = PoseSource("shifted", frozenset({"odometry"}), "odometry", "the odometry, moved",
                         "tests.test_python_api:shifted_poses")  # fmt: skip
    monkeypatch.setattr(sources, "SOURCES", (*sources.SOURCES, shifted))
    log = gridmap.read_log(CSV)
    plain = gridmap.build(gridmap.MapOptions().request(log=log))
    moved = gridmap.build(gridmap.MapOptions(pose="shifted").request(log=log))
    assert moved.map.spec.origin_x_m == pytest.approx(plain.map.spec.origin_x_m + 1.0)
    assert np.array_equal(moved.map.prob, plain.map.prob, equal_nan=True)


def test_every_commands_pose_choices_come_from_the_registry() -> None:
    from gridmap_cli.cli import cli

    for name in ("build", "batch", "trajectory", "evaluate", "calibrate"):
        command = cli.get_command(click.Context(cli), name)
        assert command is not None
        (pose,) = [p for p in command.params if p.name == "pose"]
        assert isinstance(pose.type, click.Choice)
        if name == "calibrate":  # what calibrates: the odometry and the laser's tracks
            wanted = tuple(s.name for s in SOURCES if s.needs and "reference" not in s.needs)
        elif name == "evaluate":  # the track a map was built with: never a choice
            wanted = tuple(s.name for s in SOURCES if not s.chooses)
        else:
            wanted = source_names()
        assert tuple(pose.type.choices) == wanted, name
