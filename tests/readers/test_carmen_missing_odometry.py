"""A corrected CARMEN log whose ODOM lines only repeat the corrected poses has no odometry."""

from __future__ import annotations

from pathlib import Path

import pytest

from gridmap_cli.readers.text.carmen_log import read_carmen_log
from tests.helpers import names, run
from tests.readers.carmen_helpers import flaser, odom, write

RANGES = [1.0, 2.0, 1.5] * 60


def repeating(twice: bool) -> list[str]:
    """Scans 0.3 m apart; each ODOM line restarts at the scan's corrected pose (``twice``: and
    is written again, unchanged)."""
    lines = []
    for i in range(20):
        pose = (0.3 * i, 0.01 * i, 0.0)
        lines += [flaser(RANGES, pose, 1.0 + i), odom(pose, 1.0 + i)]
        if twice:
            lines.append(odom(pose, 1.5 + i))
    return lines


def driving() -> list[str]:
    """A corrected log with real increments: ODOM drives 0.2 m between restarts."""
    lines = []
    for i in range(10):
        pose = (0.5 * i, 0.05 * i, 0.0)
        lines += [
            flaser(RANGES, pose, 1.0 + i),
            odom(pose, 0.0),
            odom((pose[0] + 0.2, 0, 0), 1.5 + i),
        ]
    return lines


@pytest.mark.parametrize("twice", [False, True])
def test_the_reader_says_the_odometry_is_missing(tmp_path: Path, twice: bool) -> None:
    log = read_carmen_log(write(tmp_path, repeating(twice)))
    assert log.odometry_missing is not None
    assert log.metadata["odometry"].startswith("missing: the ")


def test_real_increments_are_odometry(tmp_path: Path) -> None:
    log = read_carmen_log(write(tmp_path, driving()))
    assert log.odometry_missing is None
    assert log.metadata["odometry"].startswith("the robot's own")


def test_pose_odometry_refuses_it_in_one_line_and_global_maps(tmp_path: Path) -> None:
    log = write(tmp_path, repeating(False))
    out = tmp_path / "out"
    out.mkdir()
    code, _, err = run("build", str(log), "-o", str(out / "map.png"), "--pose", "odometry")
    assert code == 1
    assert err.startswith(f"Error: {log}: --pose odometry: odometry missing: ")
    assert len(err.strip().splitlines()) == 1
    assert names(out) == set()
    code, _, err = run("build", str(log), "-o", str(out / "map.png"), "--pose", "global", "-q")
    assert code == 0, err
    assert names(out) == {"map.png", "map.yaml"}


def test_inspect_says_the_odometry_is_missing(tmp_path: Path) -> None:
    code, out, err = run("inspect", str(write(tmp_path, repeating(False))))
    # build's automatic choice maps the laser with the pose graph, which needs no odometry
    assert code == 0, err
    assert "  odometry    missing: the 20 ODOM lines only repeat" in out  # the header, key a line
    assert "build would fail" not in out


def no_odom_lines() -> list[str]:
    """Laser lines alone: their poses may be a corrected log's or the robot's odometry."""
    return [flaser(RANGES, (0.3 * i, 0.01 * i, 0.0), 1.0 + i) for i in range(20)]


def test_without_odom_lines_the_laser_poses_are_the_reference_never_odometry(
    tmp_path: Path,
) -> None:
    """build and inspect say the same: --pose odometry is refused in one line naming why,
    --pose global maps with the laser lines' poses, and calibrate does not compare the
    reference with itself."""
    log = write(tmp_path, no_odom_lines())
    out = tmp_path / "out"
    out.mkdir()
    code, _, err = run("build", str(log), "-o", str(out / "map.png"), "--pose", "odometry")
    assert code == 1 and err.count("\n") == 1
    assert err.startswith(f"Error: {log}: --pose odometry: odometry missing: the log has no ODOM ")
    assert "--pose global maps with them" in err
    assert names(out) == set()
    code, out_text, _ = run("inspect", str(log))
    assert code == 0  # build's automatic choice maps the laser with the pose graph
    assert "  odometry  none: the log has no ODOM lines" in out_text  # the plan
    assert "  odometry    no ODOM lines: none the log can vouch for" in out_text  # the header
    assert "ODOM lines: the chain of their increments" not in out_text
    code, _, err = run("build", str(log), "-o", str(out / "map.png"), "--pose", "global", "-q")
    assert code == 0, err
    code, _, err = run("calibrate", str(log))
    assert code == 1
    assert err.startswith(f"Error: {log}: calibrate compares the odometry with the reference")
