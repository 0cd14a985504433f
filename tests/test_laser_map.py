"""A simulated ARIA .2d laser log builds a clean laser map (the ray model, end to end)."""

from __future__ import annotations

from pathlib import Path

from gridmap_cli.evaluation.metrics import wall_scores, walls_in_map_frame
from gridmap_cli.mapping.grid import OccupancyMap
from gridmap_cli.mapping.mapfile import load_map
from tests.helpers import run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
ROBOT = """\
gridmap-robot: 1
name: lms200-only
sensors:
  - {name: laser1, kind: laser, x_m: 0.16, y_m: 0.0, yaw_deg: 0, first_deg: -90, last_deg: 90,
     samples: 181, max_range_m: 8.0}
"""


def invoke(*args: str) -> None:
    code, _, stderr = run(*args)
    assert code == 0, stderr


def test_laser_log_maps_thin_walls_where_the_world_has_them(tmp_path: Path) -> None:
    robot = tmp_path / "lms.yaml"
    robot.write_text(ROBOT)
    log = tmp_path / "office.2d"
    invoke(
        "simulate", str(SAMPLES / "worlds" / "office.yaml"), str(SAMPLES / "paths" / "office.yaml"),
        "-o", str(log), "--robot", str(robot), "--seed", "3", "--drift", "0", "-q",
    )  # fmt: skip
    assert log.read_text().startswith("LaserOdometryLog\n")
    out = tmp_path / "office.png"
    invoke("build", str(log), "-o", str(out), "--pose", "global", "-q")

    world = load_map(SAMPLES / "worlds" / "office.yaml")
    built = load_map(out.with_suffix(".yaml"))
    # built with --pose global: the map frame is the world frame
    scores = wall_scores(
        OccupancyMap(built.spec, built.probability()),
        world.spec,
        world.occupied_mask(),
        visible_within=1,  # a laser sees wall faces, not the back of a two-cell wall
    )
    true_wall = walls_in_map_frame(built.spec, world.spec, world.occupied_mask())
    # measured at drift 0: 2563 occupied cells, all within a cell of a wall; 3296 visible wall
    # cells, none mapped free, 99.97 % with an occupied cell within one cell
    assert scores.occupied > 1000
    assert scores.false_occupied < 0.02
    assert ((built.occupancy == 0) & true_wall).sum() == 0
    assert scores.erased == 0.0
    assert scores.recall > 0.98
