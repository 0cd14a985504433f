"""Laser readings without echo and beyond ``--max-range`` (issue 21): no-echo beams clear free
space up to a cap (``--no-echo-free``, gmapping's maxUrange), long readings are cut to free
space at ``--max-range`` (slam_toolbox's max_laser_range), and neither sets the map's bounds:
a few long beams through a door do not grow a room's map."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from PIL import Image

from tests.helpers import run
from tests.readers.carmen_helpers import flaser, odom, write

HALF_M = 2.0  # the room: walls at x, y = +-2 m
DOOR_M = 0.3  # a door in the wall x = +2, |y| < 0.3


def _beam(x: float, y: float, angle: float, outside: float) -> float:
    """Range from (x, y) along ``angle`` to the room's walls; ``outside`` through the door."""
    c, s = math.cos(angle), math.sin(angle)
    hits = []
    if abs(c) > 1e-9:
        hits.append(((HALF_M if c > 0 else -HALF_M) - x) / c)
    if abs(s) > 1e-9:
        hits.append(((HALF_M if s > 0 else -HALF_M) - y) / s)
    t = min(h for h in hits if h > 0)
    through_door = c > 0 and abs(t - (HALF_M - x) / c) < 1e-9 and abs(y + t * s) < DOOR_M
    return outside if through_door else t


def room_log(tmp_path: Path, outside: float) -> Path:
    """A robot turning in place at a few spots of the room, its 180-beam laser facing the door
    for a part of each turn; beams through the door read ``outside``."""
    lines, t = [], 1.0
    for x, y in [(0.0, 0.0), (-0.5, 0.5), (0.5, -0.5)]:
        for k in range(12):
            heading = math.remainder(k * math.pi / 6, 2 * math.pi)
            pose = (x, y, heading)
            lines.append(odom(pose, t))
            # a far wall's ranges vary (a value repeated everywhere would be the no-echo code)
            far = outside if outside > 80 else outside + 0.01 * len(lines)
            ranges = [_beam(x, y, heading + math.radians(b - 90), far) for b in range(180)]
            lines.append(flaser(ranges, pose, t))
            t += 0.1
    return write(tmp_path, lines, f"room-{outside:g}.log")


def build(log: Path, folder: Path, *flags: str) -> tuple[tuple[float, float], bytes]:
    """The map's size (metres) and PNG bytes."""
    folder.mkdir()
    out = folder / "m.png"
    code, _, err = run("build", str(log), "-o", str(out), "-q", *flags)
    assert code == 0, err
    resolution = yaml.safe_load(out.with_suffix(".yaml").read_text())["resolution"]
    width, height = Image.open(out).size
    return (width * resolution, height * resolution), out.read_bytes()


ROOM_M = 2 * HALF_M + 2 * 0.2 + 0.2  # the room, the margins, a cell or two


def test_no_echo_beams_through_a_door_do_not_grow_the_map(tmp_path: Path) -> None:
    log = room_log(tmp_path, outside=81.91)  # a SICK's no-echo code
    (width, height), image = build(log, tmp_path / "default")
    assert width < ROOM_M and height < ROOM_M
    # --no-echo-free changes laser maps: the no-echo beams clear the room near the door
    _, without = build(log, tmp_path / "zero", "--no-echo-free", "0")
    assert without != image


def test_long_beams_through_a_door_grow_the_map_unless_max_range_cuts_them(
    tmp_path: Path,
) -> None:
    log = room_log(tmp_path, outside=30.0)  # a wall 30 m away, seen through the door
    (width, _), _ = build(log, tmp_path / "uncut")
    assert width > 30.0  # the far wall is an echo: it sets the bounds
    (width, height), cut = build(log, tmp_path / "cut", "--max-range", "8")
    assert width < ROOM_M and height < ROOM_M  # cut beams are free space, not bounds
    (width, _), longer = build(log, tmp_path / "longer", "--max-range", "40")
    assert width > 30.0 and longer != cut


BAD = [("--max-range", "0"), ("--max-range", "-1"), ("--max-range", "nan"),
       ("--no-echo-free", "-1")]  # fmt: skip


@pytest.mark.parametrize("flag, value", BAD)
def test_bad_range_options_are_usage_errors(tmp_path: Path, flag: str, value: str) -> None:
    log = room_log(tmp_path, outside=81.91)
    code, _, err = run("build", str(log), "-o", str(tmp_path / "m.png"), flag, value)
    assert code == 2 and err.count("\n") == 1 and flag in err, err
    assert not (tmp_path / "m.png").exists()
