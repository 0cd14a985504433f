"""A simulated ARIA .2d laser log builds a clean laser map (the ray model, end to end)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from click.testing import CliRunner
from scipy import ndimage

from gridmap_cli.cli import cli
from gridmap_cli.mapfile import load_map

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
ROBOT = """\
gridmap-robot: 1
name: lms200-only
sensors:
  - {name: laser1, kind: laser, x_m: 0.16, y_m: 0.0, yaw_deg: 0, first_deg: -90, last_deg: 90,
     samples: 181, max_range_m: 8.0}
"""


def invoke(*args: str) -> None:
    result = CliRunner().invoke(cli, list(args))
    assert result.exit_code == 0, result.stderr


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
    walls = world.occupied_mask()
    built = load_map(out.with_suffix(".yaml"))
    rows, cols = np.indices(built.occupancy.shape)
    x, y = built.spec.cell_center(cols, rows)
    wc, wr = world.spec.world_to_cell(x, y)
    inside = (wc >= 0) & (wr >= 0) & (wc < world.spec.width) & (wr < world.spec.height)
    true_wall = np.zeros(built.occupancy.shape, dtype=bool)
    true_wall[inside] = walls[wr[inside], wc[inside]]
    near_wall = ndimage.binary_dilation(true_wall, iterations=1)
    occupied = built.occupancy == 100
    free = built.occupancy == 0
    visible = true_wall & ndimage.binary_dilation(built.occupancy >= 0, iterations=1)
    # measured at drift 0: 2563 occupied cells, all within a cell of a wall; 3296 visible wall
    # cells, none mapped free, 99.97 % with an occupied cell within one cell
    assert occupied.sum() > 1000
    assert (occupied & near_wall).sum() / occupied.sum() > 0.98
    assert (free & true_wall).sum() == 0
    recall = (ndimage.binary_dilation(occupied, iterations=1) & visible).sum() / visible.sum()
    assert recall > 0.98
