"""Standard-model map quality against ground truth: the table in docs/sensor-model.md.

For each sample world, simulates a run with perfect odometry (drift 0, seed 11), builds maps
with a few settings and scores them cell by cell against the world (odometry frame = frame of
the first true pose): wall recall, walls erased, false occupied, mapped free area.

    .venv/bin/python bench/model_quality.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import ndimage

from gridmap_cli.geometry import compose
from gridmap_cli.mapfile import load_map
from gridmap_cli.models.standard import StandardSonarParams
from gridmap_cli.pipeline import BuildOptions, build_map
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import load_robot
from gridmap_cli.sim.path import load_path
from gridmap_cli.sim.simulate import simulate
from gridmap_cli.sim.world import World

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
WORLDS = ("corridor_loop", "office", "hall")
SETTINGS = {
    "defaults": {},
    "no-echo free 2.0 m": {"no_echo_free_m": 2.0},
    "no-echo free 0.5 m": {"no_echo_free_m": 0.5},
    "no-echo readings ignored": {"no_echo_free_m": 0.0},
    "p_occ 0.6": {"p_occupied": 0.6},
    "obstacle thickness 0.15 m": {"obstacle_thickness_m": 0.15},
}


def score(name: str, log: RangeLog, params: StandardSonarParams) -> tuple[float, ...]:
    world = load_map(SAMPLES / "worlds" / f"{name}.yaml")
    walls = world.occupied_mask()
    result = build_map(log, load_robot("p3at"), BuildOptions(sonar=params))
    spec, p = result.map.spec, result.map.prob
    rows, cols = np.indices(p.shape)
    cx, cy = spec.cell_center(cols, rows)
    t = log.truth
    assert t is not None
    wx, wy, _ = compose(t.x_m[0], t.y_m[0], t.theta_rad[0], cx, cy, 0.0)
    wc, wr = world.spec.world_to_cell(wx, wy)
    inside = (wc >= 0) & (wr >= 0) & (wc < world.spec.width) & (wr < world.spec.height)
    true_wall = np.zeros(p.shape, bool)
    true_near = np.zeros(p.shape, bool)
    true_wall[inside] = walls[wr[inside], wc[inside]]
    true_near[inside] = ndimage.binary_dilation(walls, iterations=1)[wr[inside], wc[inside]]
    known = ~np.isnan(p)
    occupied, free = known & (p >= 0.65), known & (p <= 0.25)
    visible = true_wall & ndimage.binary_dilation(known, iterations=2)
    recall = (visible & ndimage.binary_dilation(occupied, iterations=1)).sum() / visible.sum()
    erased = (visible & free).sum() / visible.sum()
    false_occupied = (occupied & ~true_near).sum() / max(occupied.sum(), 1)
    return recall, erased, false_occupied, free.sum() * spec.resolution_m**2


def main() -> None:
    robot = load_robot("p3at")
    logs = {}
    for name in WORLDS:
        loaded = load_map(SAMPLES / "worlds" / f"{name}.yaml")
        path = load_path(SAMPLES / "paths" / f"{name}.yaml")
        logs[name] = simulate(
            World(loaded.occupied_mask(), loaded.spec), path, robot, seed=11, drift=0.0
        )
    print("recall / erased / false occupied, free m^2, per world:", ", ".join(WORLDS))
    for label, kwargs in SETTINGS.items():
        cells = []
        for name in WORLDS:
            r, e, f, a = score(name, logs[name], StandardSonarParams(**kwargs))
            cells.append(f"{r:.2f} / {e:.2f} / {f:.2f}, {a:.0f} m^2")
        print(f"{label:28s} | " + " | ".join(cells))


if __name__ == "__main__":
    main()
