"""Shared fixtures: tiny logs built in code."""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest
from hypothesis import settings

from gridmap_cli.robot import load_robot


def room_log_text(turns: int = 200, half_size_m: float = 2.0, robot: str = "p3dx") -> str:
    """A robot spinning in place at the centre of a square room, as a CSV log.

    Each sonar reads the distance along its axis to the nearest wall (x or y = +-half_size_m);
    a range beyond the sonar's maximum is written as the maximum (no echo).
    """
    desc = load_robot(robot)
    lines = [
        "# gridmap-csv: 1",
        f"# robot: {robot}",
        "time,x,y,theta," + ",".join(s.name for s in desc.sensors),
    ]
    for k in range(turns):
        th = math.remainder(k * 2 * math.pi / turns, 2 * math.pi)
        values = []
        for s in desc.sensors:
            sx = math.cos(th) * s.x_m - math.sin(th) * s.y_m
            sy = math.sin(th) * s.x_m + math.cos(th) * s.y_m
            a = th + s.yaw_rad
            c, si = math.cos(a), math.sin(a)
            hits = []
            if abs(c) > 1e-9:
                hits.append(((half_size_m if c > 0 else -half_size_m) - sx) / c)
            if abs(si) > 1e-9:
                hits.append(((half_size_m if si > 0 else -half_size_m) - sy) / si)
            values.append(f"{min(min(hits), s.max_range_m):.4f}")
        lines.append(f"{k / 10:.1f},0.0,0.0,{th:.6f}," + ",".join(values))
    return "\n".join(lines) + "\n"


@pytest.fixture
def room_csv(tmp_path: Path) -> Path:
    path = tmp_path / "room.csv"
    path.write_text(room_log_text())
    return path


# CI runs the same examples every time (a failure there blocks landing and must be reproducible);
# local runs keep exploring new ones.
if os.environ.get("CI"):
    settings.register_profile("ci", derandomize=True, print_blob=True)
    settings.load_profile("ci")
