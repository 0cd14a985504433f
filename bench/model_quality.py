"""Standard-model map quality against ground truth: the table in docs/sensor-model.md.

For each sample world, simulates a run with perfect odometry (drift 0, seed 11), builds maps
with a few settings and scores them cell by cell against the world (odometry frame = frame of
the first true pose): wall recall, walls erased, false occupied, mapped free area.

    .venv/bin/python bench/model_quality.py
"""

from __future__ import annotations

from pathlib import Path

from gridmap_cli.evaluation.metrics import WallScores, wall_scores
from gridmap_cli.mapping.mapfile import load_map
from gridmap_cli.mapping.models.standard import StandardSonarParams
from gridmap_cli.mapping.pipeline import BuildOptions, build_map
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


def score(name: str, log: RangeLog, params: StandardSonarParams) -> WallScores:
    world = load_map(SAMPLES / "worlds" / f"{name}.yaml")
    result = build_map(log, load_robot("p3at"), BuildOptions(sonar=params))
    t = log.truth
    assert t is not None
    # the odometry frame is the frame of the first true pose
    start = (float(t.x_m[0]), float(t.y_m[0]), float(t.theta_rad[0]))
    return wall_scores(result.map, world.spec, world.occupied_mask(), start)


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
            w = score(name, logs[name], StandardSonarParams(**kwargs))
            cells.append(
                f"{w.recall:.2f} / {w.erased:.2f} / {w.false_occupied:.2f}, {w.free_m2:.0f} m^2"
            )
        print(f"{label:28s} | " + " | ".join(cells))


if __name__ == "__main__":
    main()
