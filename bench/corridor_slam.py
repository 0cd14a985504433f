"""Issue 20: `--pose slam` in long, featureless corridors, measured against ground truth.

Builds a ring of corridors (two 55 m corridors with nothing on their walls, joined by two short
ones with a door recess each), drives the simulated `p3at-lms200` round it once and on along the
first corridor again (so a loop closes at a corner, and the second pass runs along a corridor
already mapped), with poor odometry (`--drift 2`), then for odometry, scan-matched and slam:

- the trajectory's APE (RMS after a rigid SE(2) fit, as `evo_ape -a`) against the truth, at the
  scans' stamps, and its error along the corridors (the degenerate direction);
- the map's F1 from `gridmap evaluate` against the world (standard build, scale mode);
- the slam summary (closures accepted, rejected, warning).

Everything goes through the `gridmap` command as a user runs it; the world, path, log, maps and
PNGs land in ``out/corridor/``:

    .venv/bin/python bench/corridor_slam.py            # table on stdout
    .venv/bin/python bench/corridor_slam.py --seed 4 --drift 3
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from gridmap_cli.mapping.grid import GridSpec, OccupancyMap
from gridmap_cli.poses.sync import interpolate_pose
from gridmap_cli.poses.track_error import track_error
from gridmap_cli.readers import read_logs
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.records import PoseTrack
from gridmap_cli.writers.map_image import write_map

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "out" / "corridor"
RES = 0.05
GRIDMAP = Path(sys.executable).with_name("gridmap")


def corridor_ring(path_yaml: Path, world_pgm: Path) -> None:
    """The world (PGM + YAML beside it) and the path file."""
    # the building is 62 x 16 m; the grid reaches 20 m beyond it, so that an odometry map
    # drifted out of the building still lies mostly inside the world evaluate scores on
    ox, oy, w, h = -20.0, -20.0, 102.0, 56.0
    occ = np.zeros((round(h / RES), round(w / RES)), dtype=bool)

    def box(x0: float, y0: float, x1: float, y1: float, value: bool = True) -> None:
        r0, r1 = round((y0 - oy) / RES), round((y1 - oy) / RES)
        occ[r0:r1, round((x0 - ox) / RES) : round((x1 - ox) / RES)] = value

    def rect(x0: float, y0: float, x1: float, y1: float, t: float = 0.1) -> None:
        box(x0 - t / 2, y0 - t / 2, x1 + t / 2, y0 + t / 2)
        box(x0 - t / 2, y1 - t / 2, x1 + t / 2, y1 + t / 2)
        box(x0 - t / 2, y0 - t / 2, x0 + t / 2, y1 + t / 2)
        box(x1 - t / 2, y0 - t / 2, x1 + t / 2, y1 + t / 2)

    rect(1.0, 1.0, 61.0, 15.0)  # outer wall
    rect(3.4, 3.4, 58.6, 12.6)  # inner block: corridors 2.4 m wide
    # a door recess in each short corridor's outer wall, nothing in the long ones
    box(0.35, 5.95, 1.05, 7.05)  # left: a recess 0.6 m deep, 1 m wide
    box(0.45, 6.05, 1.06, 6.95, value=False)
    box(60.95, 8.95, 61.65, 10.05)  # right
    box(60.94, 9.05, 61.55, 9.95, value=False)
    write_map(
        world_pgm,
        OccupancyMap(GridSpec(ox, oy, RES, occ.shape[1], occ.shape[0]), occ.astype(np.float64)),
        mode="trinary",
        force=True,
    )
    pts = [(2.2, 2.2), (59.8, 2.2), (59.8, 13.8), (2.2, 13.8), (2.2, 2.2), (30.0, 2.2)]
    path_yaml.write_text(
        "gridmap-path: 1\nwaypoints: ["
        + ", ".join(f"[{x}, {y}]" for x, y in pts)
        + "]\nspeed_m_s: 1.0\nturn_rate_deg_s: 40\n"
    )


def gridmap(*args: str) -> str:
    done = subprocess.run([str(GRIDMAP), *args], capture_output=True, text=True, cwd=ROOT)
    if done.returncode != 0:
        raise SystemExit(f"gridmap {' '.join(args)} failed:\n{done.stderr}")
    return done.stdout


def read_tum(path: Path) -> PoseTrack:
    rows = np.loadtxt(path, ndmin=2)
    theta = 2 * np.arctan2(rows[:, 6], rows[:, 7])
    return PoseTrack(
        stamp_ns=np.round(rows[:, 0] * 1e9).astype(np.int64),
        x_m=rows[:, 1].copy(), y_m=rows[:, 2].copy(), theta_rad=theta,
    )  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--drift", type=float, default=2.0)
    ap.add_argument("--reuse", action="store_true", help="keep OUT/run.csv if there")
    ap.add_argument("--out", type=Path, default=OUT, help="folder for everything written")
    args = ap.parse_args()
    out_dir: Path = args.out
    out_dir.mkdir(parents=True, exist_ok=True)
    world, path, log = out_dir / "world.yaml", out_dir / "path.yaml", out_dir / "run.csv"
    corridor_ring(path, world.with_suffix(".pgm"))
    if not (args.reuse and log.exists()):
        gridmap(
            "simulate",
            str(world),
            str(path),
            "-o",
            str(log),
            "--robot",
            "p3at-lms200",
            "--seed",
            str(args.seed),
            "--drift",
            str(args.drift),
            "--force",
            "--quiet",
        )
    data = read_logs((log,), None, ReadOptions())
    truth = data.truth
    assert truth is not None
    rows = []
    slam_summary: dict[str, object] = {}
    scan_stamps: np.ndarray | None = None
    for pose in ("scan-matched", "slam", "odometry"):
        tum = out_dir / f"{pose}.tum"
        out = gridmap("trajectory", str(log), "--pose", pose, "-o", str(tum), "--force", "--json")
        if pose == "slam":
            slam_summary = json.loads(out)["slam"]
        track = read_tum(tum)
        if scan_stamps is None:
            scan_stamps = track.stamp_ns
        keep = np.isin(track.stamp_ns, scan_stamps)
        track = PoseTrack(track.stamp_ns[keep], track.x_m[keep], track.y_m[keep],
                          track.theta_rad[keep])  # fmt: skip
        tx, ty, tth, _ = interpolate_pose(truth, track.stamp_ns)
        err = track_error(track, PoseTrack(track.stamp_ns, tx, ty, tth))
        png = out_dir / f"{pose}.png"
        gridmap(
            "build",
            str(log),
            "--pose",
            pose,
            "-o",
            str(png),
            "--map-mode",
            "scale",
            "--force",
            "--quiet",
        )
        ev = json.loads(gridmap("evaluate", str(png.with_suffix(".yaml")), "--truth", str(world),
                                "--log", str(log), "--pose", pose, "--json"))  # fmt: skip
        rows.append((pose, err.ape_rmse_m, err.ape_max_m, err.ape_heading_deg, ev))
    print("| track | APE RMS m | APE max m | heading RMS deg | F1 | NLL |")
    print("|---|---|---|---|---|---|")
    for pose, rms, mx, head, ev in sorted(rows, key=lambda r: ["odometry", "scan-matched",
                                                              "slam"].index(r[0])):  # fmt: skip
        print(f"| {pose} | {rms:.2f} | {mx:.2f} | {head:.2f} | {ev['f1']:.3f} | {ev['nll']:.3f} |")
    print(json.dumps(slam_summary, indent=1))


if __name__ == "__main__":
    main()
