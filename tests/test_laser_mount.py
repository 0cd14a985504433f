"""The laser's mounting measured against the odometry's turns (gridmap_cli/poses/laser_mount.py):
a synthetic run whose laser sits where its mounting does not say, and a simulated ROS bag built
with the wrong mounting on the command line."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.geometry import compose, inverse
from gridmap_cli.poses.laser_mount import TOLERANCE_M, check_mount
from gridmap_cli.records import PoseTrack, RangeLog
from tests.helpers import run
from tests.readers.pioneer_bag import write_pioneer_bag
from tests.test_pioneer_bag import pioneer  # noqa: F401  (the fixture)


def _run(
    laser_at: tuple[float, float],
    given: tuple[float, float],
    seed: int = 0,
    turning: bool = True,
    scale: float = 1.03,
    drift_rad_per_m: float = 0.01,
) -> tuple[PoseTrack, PoseTrack]:
    """A robot driving and turning (``turning``) for 2,000 steps: the scan matcher's track (the
    base frame's poses found with the laser taken at ``given``, while it sits at ``laser_at``,
    a few millimetres of noise) and the odometry's (its distance ``scale`` times the truth, its
    heading drifting ``drift_rad_per_m``)."""
    rng = np.random.default_rng(seed)
    n = 2000
    forward = rng.uniform(0.0, 0.06, n)
    turn = rng.normal(0.0, 0.08, n) if turning else np.zeros(n)
    x, y, th = np.zeros(n), np.zeros(n), np.zeros(n)
    ox, oy, oth = np.zeros(n), np.zeros(n), np.zeros(n)
    for k in range(1, n):
        x[k], y[k], th[k] = compose(x[k - 1], y[k - 1], th[k - 1], forward[k], 0.0, turn[k])
        ox[k], oy[k], oth[k] = compose(
            ox[k - 1], oy[k - 1], oth[k - 1], scale * forward[k], 0.0,
            turn[k] + drift_rad_per_m * forward[k],
        )  # fmt: skip
    # the laser's true poses, then the base as a matcher assuming ``given`` puts it
    lx, ly, lth = compose(x, y, th, laser_at[0], laser_at[1], 0.0)
    noise = rng.normal(0.0, 0.003, (3, n))
    lx, ly, lth = lx + noise[0], ly + noise[1], lth + 0.1 * noise[2]
    bx, by, bth = compose(lx, ly, lth, *inverse(given[0], given[1], 0.0))
    stamps = np.arange(n, dtype=np.int64) * 100_000_000
    return PoseTrack(stamps, bx, by, bth), PoseTrack(stamps, ox, oy, oth)


@pytest.mark.parametrize("laser_at", [(0.12, -0.03), (-0.25, 0.0), (0.0, 0.08)])
def test_a_laser_off_its_mounting_is_measured_where_it_is(laser_at: tuple[float, float]) -> None:
    track, odometry = _run(laser_at, given=(0.0, 0.0))
    check = check_mount(track, odometry, (0.0, 0.0))
    assert check is not None
    assert math.hypot(check.x_m - laser_at[0], check.y_m - laser_at[1]) < 0.01
    assert check.spread_m < 0.01
    assert (
        check.disagrees
        and "check the laser's mounting where the log takes it from" in check.reason()
    )
    assert "gridmap inspect" in check.reason()  # which says where, for any format
    # the odometry's distance scale is taken out, not read as a lever
    assert abs(check.distance_scale - 1.03) < 0.005


def test_a_right_mounting_is_not_doubted() -> None:
    track, odometry = _run((0.2, 0.05), given=(0.2, 0.05), seed=1)
    check = check_mount(track, odometry, (0.2, 0.05))
    assert check is not None and check.off_m < TOLERANCE_M / 2
    assert not check.disagrees
    assert check.as_dict()["disagrees"] is False


def test_a_mounting_a_little_off_is_within_the_tolerance() -> None:
    track, odometry = _run((0.21, 0.0), given=(0.2, 0.0), seed=2)
    check = check_mount(track, odometry, (0.2, 0.0))
    assert check is not None and not check.disagrees


def test_a_robot_that_never_turns_does_not_measure_its_laser() -> None:
    track, odometry = _run((0.3, 0.0), given=(0.0, 0.0), turning=False, drift_rad_per_m=0.0)
    assert check_mount(track, odometry, (0.0, 0.0)) is None


def _trajectory(bag: Path, mount: str, out: Path) -> tuple[dict[str, object], str]:
    code, stdout, stderr = run("trajectory", str(bag), "--pose", "slam", "-o", str(out),
                               "--laser-mount", mount, "--json")  # fmt: skip
    assert code == 0, stderr
    return json.loads(stdout)["slam"]["laser_mount"], stderr


def test_a_bag_mapped_with_the_wrong_laser_mounting_is_warned_of(
    pioneer: tuple[Path, RangeLog],  # noqa: F811
    tmp_path: Path,
) -> None:
    """The simulated Pioneer's laser sits 0.16 m ahead of its base; given 0.36 m on the command
    line, the slam run measures it where it is and says so; given 0.16 m, it says nothing."""
    _, log = pioneer
    bag = write_pioneer_bag(log, tmp_path / "bare.bag", mounting=None)
    wrong, stderr = _trajectory(bag, "0.36,0,0", tmp_path / "wrong.tum")
    assert wrong["disagrees"] is True
    assert abs(float(wrong["x_m"]) - 0.16) < 0.02 and abs(float(wrong["y_m"])) < 0.02  # type: ignore[arg-type]
    assert "Warning: --pose slam: the odometry's turns put the laser at x 0.1" in stderr
    right, stderr = _trajectory(bag, "0.16,0,0", tmp_path / "right.tum")
    assert right["disagrees"] is False and "laser's mounting" not in stderr


def test_laser_mount_on_the_command_line_wins_over_a_recorded_tf(
    pioneer: tuple[Path, RangeLog],  # noqa: F811
    tmp_path: Path,
) -> None:
    """A recorded TF cannot be mended by its user: --laser-mount gives the recording's one
    laser another mounting. Given TF's own (0.16 m) it changes nothing; given 0.36 m, inspect
    says where the mounting came from and the check measures the laser where TF had it."""
    _, log = pioneer
    bag = write_pioneer_bag(log, tmp_path / "tf.bag", mounting=(0.16, 0.0, 0.0))
    plain = tmp_path / "plain.tum"
    code, _, stderr = run("trajectory", str(bag), "--pose", "slam", "-o", str(plain))
    assert code == 0, stderr
    same, _ = _trajectory(bag, "0.16,0,0", tmp_path / "same.tum")
    assert plain.read_bytes() == (tmp_path / "same.tum").read_bytes()
    assert same["given_x_m"] == 0.16 and same["disagrees"] is False
    wrong, stderr = _trajectory(bag, "0.36,0,0", tmp_path / "wrong.tum")
    assert wrong["given_x_m"] == 0.36 and wrong["disagrees"] is True
    assert abs(float(wrong["x_m"]) - 0.16) < 0.02  # type: ignore[arg-type]
    code, stdout, stderr = run("inspect", str(bag), "--laser-mount", "0.36,0,0", "--json")
    assert code == 0, stderr
    sensors = json.loads(stdout)["log"]["sensors"]
    assert {s["mounting_from"] for s in sensors} == {"--laser-mount over TF"}
    assert {s["mounting"]["x_m"] for s in sensors} == {0.36}
