"""Regenerate samples/: worlds (map_server maps), paths (waypoints) and the logs simulated on them.

Run with `make samples`. Worlds are drawn here in code (walls 10 cm thick on a 5 cm grid) and
written with gridmap's own map writer; logs come from the `gridmap simulate` command, exactly as
a user would run it, with fixed seeds so that the result is reproducible.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from gridmap_cli.mapping.grid import GridSpec, OccupancyMap
from gridmap_cli.writers.map_image import write_map

HERE = Path(__file__).resolve().parent
RES = 0.05


class Canvas:
    """A world under construction: occupied cells in a grid with origin (0, 0)."""

    def __init__(self, width_m: float, height_m: float) -> None:
        self.spec = GridSpec(0.0, 0.0, RES, round(width_m / RES), round(height_m / RES))
        self.occ = np.zeros(self.spec.shape, dtype=bool)

    def box(self, x0: float, y0: float, x1: float, y1: float, value: bool = True) -> None:
        """Fill the axis-aligned box [x0, x1] x [y0, y1] (metres)."""
        c0, c1 = round(x0 / RES), round(x1 / RES)
        r0, r1 = round(y0 / RES), round(y1 / RES)
        self.occ[r0:r1, c0:c1] = value

    def wall(self, x0: float, y0: float, x1: float, y1: float, t: float = 0.1) -> None:
        """An axis-aligned wall of thickness t from (x0, y0) to (x1, y1)."""
        if y0 == y1:
            self.box(min(x0, x1), y0 - t / 2, max(x0, x1), y0 + t / 2)
        else:
            self.box(x0 - t / 2, min(y0, y1), x0 + t / 2, max(y0, y1))

    def rect(self, x0: float, y0: float, x1: float, y1: float, t: float = 0.1) -> None:
        for a in ((x0, y0, x1, y0), (x0, y1, x1, y1), (x0, y0, x0, y1), (x1, y0, x1, y1)):
            self.wall(*a, t=t)
        self.box(x1 - t / 2, y1 - t / 2, x1 + t / 2, y1 + t / 2)  # close the corner

    def pillar(self, x: float, y: float, size: float) -> None:
        self.box(x - size / 2, y - size / 2, x + size / 2, y + size / 2)

    def save(self, name: str) -> None:
        prob = self.occ.astype(np.float64)
        write_map(
            HERE / "worlds" / f"{name}.pgm",
            OccupancyMap(self.spec, prob),
            mode="trinary",
            force=True,
        )


def corridor_loop() -> tuple[Canvas, list[tuple[float, float]]]:
    """A ring corridor, 2 m wide, around a block of offices: the classic sonar-mapping loop."""
    c = Canvas(22.0, 14.0)
    c.rect(1.0, 1.0, 21.0, 13.0)  # outer wall
    c.rect(3.0, 3.0, 19.0, 11.0)  # inner block
    # door recesses in the outer wall and a pillar, so the corridor is not featureless
    for x in (6.0, 12.0, 17.0):
        c.box(x, 13.0 - 0.05, x + 1.0, 13.5)
        c.rect(x, 13.0, x + 1.0, 13.5)
        c.box(x + 0.05, 12.9, x + 0.95, 13.45, value=False)
    c.box(9.0, 0.5, 10.0, 1.05)
    c.rect(9.0, 0.5, 10.0, 1.0)
    c.box(9.05, 0.55, 9.95, 1.1, value=False)
    c.pillar(14.0, 1.6, 0.3)
    path = [(2.0, 2.0), (20.0, 2.0), (20.0, 12.0), (2.0, 12.0), (2.0, 2.0)]
    return c, path


def office() -> tuple[Canvas, list[tuple[float, float]]]:
    """A straight corridor with three rooms off it; the robot visits two of them."""
    c = Canvas(20.0, 12.0)
    c.rect(1.0, 1.0, 19.0, 11.0)  # building
    c.wall(1.0, 3.0, 19.0, 3.0)  # corridor (y 1..3) / rooms (y 3..11)
    for x in (7.0, 13.0):
        c.wall(x, 3.0, x, 11.0)
    for x in (3.5, 9.5, 15.5):  # 1 m doorways
        c.box(x, 2.9, x + 1.0, 3.1, value=False)
    c.box(4.0, 8.5, 6.0, 10.0)  # a cupboard in room 1
    c.pillar(10.0, 7.0, 0.4)  # a column in room 2
    c.box(15.0, 9.0, 18.0, 10.0)  # a bench in room 3
    path = [
        (2.0, 2.0),
        (4.0, 2.0),
        (4.0, 6.0),
        (2.5, 6.0),
        (2.5, 4.0),
        (4.0, 4.0),
        (4.0, 2.0),
        (10.0, 2.0),
        (10.0, 5.0),
        (11.5, 5.0),
        (11.5, 9.5),
        (8.5, 9.5),
        (8.5, 5.0),
        (10.0, 5.0),
        (10.0, 2.0),
        (18.0, 2.0),
    ]
    return c, path


def hall() -> tuple[Canvas, list[tuple[float, float]]]:
    """An open hall with pillars and crates: few walls, many corners."""
    c = Canvas(16.0, 13.0)
    c.rect(1.0, 1.0, 15.0, 12.0)
    for x in (5.0, 11.0):
        for y in (4.5, 8.5):
            c.pillar(x, y, 0.5)
    c.box(7.0, 6.0, 9.0, 7.0)
    c.box(2.0, 10.0, 3.5, 11.0)
    c.box(12.5, 2.0, 14.0, 3.0)
    # clear of every pillar and crate by at least 0.7 m (the P3-AT is 0.5 m wide)
    path = [
        (2.5, 2.5), (11.0, 2.5), (13.5, 4.0), (13.5, 10.5), (8.0, 10.5), (8.0, 8.0),
        (3.0, 6.5), (3.0, 2.5), (2.5, 2.5),
    ]  # fmt: skip
    return c, path


def write_path(name: str, waypoints: list[tuple[float, float]], laps: int = 1) -> Path:
    path = HERE / "paths" / f"{name}.yaml"
    pts = ", ".join(f"[{x}, {y}]" for x, y in waypoints)
    path.write_text(
        "# waypoints in the world frame (metres); see gridmap_cli/sim/path.py\n"
        f"gridmap-path: 1\nwaypoints: [{pts}]\nspeed_m_s: 0.4\nturn_rate_deg_s: 40\nlaps: {laps}\n"
    )
    return path


def simulate(gridmap: Path, world: Path, path: Path, out: Path, seed: int, *extra: str) -> None:
    """Run `gridmap simulate` from the repository root with relative paths, so that the logs'
    metadata is the same on every machine."""
    root = HERE.parent
    subprocess.run(
        [
            str(gridmap), "simulate", str(world.relative_to(root)), str(path.relative_to(root)),
            "-o", str(out.relative_to(root)), "--robot", "p3at", "--seed", str(seed),
            "--drift", "1", "--force", "--quiet", *extra,
        ],
        check=True,
        cwd=root,
    )  # fmt: skip
    print(f"wrote {out.relative_to(root)}")


def main() -> None:
    (HERE / "worlds").mkdir(exist_ok=True)
    (HERE / "paths").mkdir(exist_ok=True)
    gridmap = Path(sys.executable).with_name("gridmap")
    for seed, (name, make) in enumerate(
        (("corridor_loop", corridor_loop), ("office", office), ("hall", hall)), start=1
    ):
        canvas, waypoints = make()
        canvas.save(name)
        path = write_path(name, waypoints)
        world = HERE / "worlds" / f"{name}.yaml"
        simulate(gridmap, world, path, HERE / f"{name}.csv", seed)
        if name == "corridor_loop":
            # the same run as an ARIA .2d log: it must build the same map as the CSV
            simulate(gridmap, world, path, HERE / f"{name}.2d", seed)
            # and as MCAP, with gridmap's JSON channels and with standard ROS 2 messages
            simulate(gridmap, world, path, HERE / f"{name}.mcap", seed)
            simulate(gridmap, world, path, HERE / f"{name}_ros2.mcap", seed, "--encoding", "ros2")


if __name__ == "__main__":
    main()
