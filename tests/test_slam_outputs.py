"""What --pose slam gives besides the track: each pose's covariance from the graph (trajectory),
and error-aware maps faded and sampled by the graph's belief (build)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.writers.csv_log import save_csv_log
from gridmap_cli.writers.trajectory import COVARIANCE_HEADER
from tests.helpers import names, run
from tests.test_scan_match import room_world
from tests.test_scan_match import run as simulate_run

LOOP = [[2, 1.5], [10, 1.5], [10, 6.5], [2, 6.5], [2, 1.5]]


@pytest.fixture(scope="module")
def loop_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A drifting laser run once round the room, ending where it started."""
    log = simulate_run(room_world(), LOOP, drift=3.0)
    log.metadata["robot"] = "p3at-lms200"
    path = tmp_path_factory.mktemp("loop") / "run.csv"
    save_csv_log(log, path)
    return path


def _covariance(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stamps (N,), covariances (N, 3, 3) and keyframe flags (N,) of a covariance CSV."""
    rows = np.loadtxt(path, delimiter=",", skiprows=1)
    xx, xy, xt, yy, yt, tt = rows[:, 1:7].T
    cov = np.stack([np.stack([xx, xy, xt], 1), np.stack([xy, yy, yt], 1),
                    np.stack([xt, yt, tt], 1)], 1)  # fmt: skip
    return rows[:, 0], cov, rows[:, 7].astype(bool)


def test_trajectory_writes_each_poses_covariance_beside_the_track(
    loop_csv: Path, tmp_path: Path
) -> None:
    out = tmp_path / "slam.tum"
    code, stdout, stderr = run("trajectory", str(loop_csv), "--pose", "slam", "-o", str(out),
                               "--json")  # fmt: skip
    assert code == 0, stderr
    cov_path = tmp_path / "slam.cov.csv"
    summary = json.loads(stdout)
    assert summary["covariance"] == str(cov_path) and f"-> {cov_path}" in stderr
    assert cov_path.read_text().splitlines()[0] == COVARIANCE_HEADER
    track = np.loadtxt(out)
    stamps, cov, keyframe = _covariance(cov_path)
    # one row per pose of the track, same stamps, the graph's nodes flagged
    assert cov.shape == (track.shape[0], 3, 3) and np.allclose(stamps, track[:, 0])
    assert keyframe.sum() == summary["slam"]["keyframes"]
    # positive-definite past the anchored first pose
    assert np.linalg.eigvalsh(cov[1:]).min() > 0.0
    # the loop closed: the end, back at the start, is surer than the far side of the room was
    assert summary["slam"]["closures_accepted"] >= 1
    position = cov[:, 0, 0] + cov[:, 1, 1]
    assert position[-1] < 0.5 * position.max()


def test_the_covariance_file_is_refused_before_reading_when_it_exists(
    loop_csv: Path, tmp_path: Path
) -> None:
    (tmp_path / "slam.cov.csv").write_text("keep")
    out = tmp_path / "slam.tum"
    code, _, stderr = run("trajectory", str(loop_csv), "--pose", "slam", "-o", str(out))
    assert code == 1 and "slam.cov.csv exists (use --force" in stderr.strip().splitlines()[-1]
    assert names(tmp_path) == {"slam.cov.csv"} and (tmp_path / "slam.cov.csv").read_text() == "keep"


def test_other_poses_write_no_covariance(loop_csv: Path, tmp_path: Path) -> None:
    out = tmp_path / "odo.tum"
    code, _, stderr = run("trajectory", str(loop_csv), "--pose", "odometry", "-o", str(out))
    assert code == 0, stderr
    assert names(tmp_path) == {"odo.tum"}


@pytest.mark.parametrize("samples", ["16", "0"])
def test_error_aware_slam_maps_take_the_graphs_uncertainty(
    loop_csv: Path, tmp_path: Path, samples: str
) -> None:
    """No odometry-error file is needed: the pose graph says how sure each pose is; the map is
    the slam map faded (analytic) or averaged over draws (sampled), never the standard one."""
    maps = {}
    for mode in ("standard", "error-aware"):
        out = tmp_path / f"{mode}.png"
        extra = ["--error-samples", samples] if mode == "error-aware" else []
        args = ["--pose", "slam", "--mode", mode, *extra, "--map-mode", "scale"]
        code, stdout, stderr = run("build", str(loop_csv), *args, "-o", str(out), "--json")
        assert code == 0, stderr
        maps[mode] = out.read_bytes()
        summary = json.loads(stdout)
    assert maps["error-aware"] != maps["standard"]
    assert summary["cells"]["observed"] > 1000


def test_error_aware_odometry_still_needs_the_odometry_error(
    loop_csv: Path, tmp_path: Path
) -> None:
    out = tmp_path / "m.png"
    code, _, stderr = run(
        "build", str(loop_csv), "--mode", "error-aware", "--pose", "odometry", "-o", str(out)
    )
    assert code == 2 and "--odometry-error FILE" in stderr and names(tmp_path) == set()


SAMPLES = Path(__file__).resolve().parents[1] / "samples"
CORRIDOR = SAMPLES / "worlds" / "corridor_loop.yaml"


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (("--pose", "global", "--frame", "odometry"), "--pose global is in the world frame"),
        (("--pose", "slam", "--frame", "world"), "--pose slam is in the odometry frame"),
        (("--pose", "slam", "--spread-plot", "s.png", "--odometry-error", "o.yaml"),
         "the pose spread is the pose graph's own"),
    ],
)  # fmt: skip
def test_evaluate_pose_usage_errors(tmp_path: Path, flags: tuple[str, ...], message: str) -> None:
    args = [str(tmp_path / f) if f.endswith((".png", ".yaml")) else f for f in flags]
    code, _, stderr = run("evaluate", str(CORRIDOR), "--truth", str(CORRIDOR),
                          "--log", str(SAMPLES / "corridor_loop.csv"), *args)  # fmt: skip
    assert code == 2 and message in stderr.strip().splitlines()[-1]
    assert names(tmp_path) == set()


def test_evaluate_a_slam_map_and_draw_the_graphs_spread(tmp_path: Path) -> None:
    """A slam map sits in the odometry frame (scored as an odometry map is placed); its spread
    plot is the pose graph's uncertainty, with no odometry-error file."""
    log = tmp_path / "run.csv"
    path = SAMPLES / "paths" / "corridor_loop.yaml"
    code, _, stderr = run("simulate", str(CORRIDOR), str(path), "--robot", "p3at-lms200",
                          "--rate", "2", "-o", str(log), "-q")  # fmt: skip
    assert code == 0, stderr
    image = tmp_path / "slam.png"
    code, _, stderr = run("build", str(log), "--pose", "slam", "--map-mode", "scale",
                          "-o", str(image), "-q")  # fmt: skip
    assert code == 0, stderr
    base = ["evaluate", str(image.with_suffix(".yaml")), "--truth", str(CORRIDOR),
            "--log", str(log), "--json"]  # fmt: skip
    plot = tmp_path / "spread.png"
    code, stdout, stderr = run(*base, "--pose", "slam", "--spread-plot", str(plot))
    assert code == 0, stderr
    slam = json.loads(stdout)
    assert slam["pose"] == "slam" and slam["frame"] == "odometry"
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code, stdout, stderr = run(*base)  # placed as an odometry map is: the same scores
    assert code == 0, stderr
    assert json.loads(stdout)["map_to_world"] == slam["map_to_world"]
    assert json.loads(stdout)["nll"] == slam["nll"]
