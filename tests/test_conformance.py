"""The same simulated run stored as CSV and as ARIA .2d is the same data and the same map.

Formats are containers, not models: whatever a log is stored in, gridmap must read back the same
canonical records (after sync: the same readings with the same sensor poses) and write the same
map bytes, in every map mode.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.mapfile import load_map
from gridmap_cli.pipeline import BuildOptions, build_map
from gridmap_cli.readers import read_log
from gridmap_cli.robot import load_robot
from gridmap_cli.sim.path import parse_path_yaml
from gridmap_cli.sim.simulate import simulate
from gridmap_cli.sim.world import World
from gridmap_cli.sync import synchronise
from gridmap_cli.writers.aria_log import save_aria_log
from gridmap_cli.writers.csv_log import save_csv_log
from gridmap_cli.writers.map_image import write_map

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
PATH = "gridmap-path: 1\nwaypoints: [[2.0, 2.0], [12.0, 2.0], [20.0, 2.0], [20.0, 6.0]]\n"


@pytest.fixture(scope="module")
def stored(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    loaded = load_map(SAMPLES / "worlds" / "corridor_loop.yaml")
    robot = load_robot("p3at")
    log = simulate(
        World(loaded.occupied_mask(), loaded.spec),
        parse_path_yaml(PATH, "inline.yaml"),
        robot,
        seed=4,
        drift=1.0,
    )
    folder = tmp_path_factory.mktemp("conformance")
    log.metadata["robot"] = "p3at"
    save_csv_log(log, folder / "run.csv")
    save_aria_log(log, robot.sensors, folder / "run.2d")
    return folder / "run.csv", folder / "run.2d"


def test_both_formats_read_back_the_same_records(stored: tuple[Path, Path]) -> None:
    csv_path, aria_path = stored
    a, b = read_log(csv_path), read_log(aria_path)
    robot = load_robot("p3at")
    for track_a, track_b in ((a.poses, b.poses), (a.truth, b.truth)):
        assert track_a is not None and track_b is not None
        for field in ("stamp_ns", "x_m", "y_m", "theta_rad"):
            assert np.array_equal(getattr(track_a, field), getattr(track_b, field)), field
    ra, sa = synchronise(a, robot)
    rb, sb = synchronise(b, robot)
    assert sa == sb
    assert ra.sensors == rb.sensors  # the .2d header's sonarUnit lines give the preset geometry
    for field in ("stamp_ns", "sensor", "range_m", "x_m", "y_m", "theta_rad"):
        assert np.array_equal(getattr(ra, field), getattr(rb, field)), field


@pytest.mark.parametrize(
    ("mode", "suffix"), [("trinary", ".pgm"), ("scale", ".png"), ("raw", ".png")]
)
def test_both_formats_build_byte_identical_maps(
    stored: tuple[Path, Path], tmp_path: Path, mode: str, suffix: str
) -> None:
    images = []
    for i, log_path in enumerate(stored):
        result = build_map(read_log(log_path), load_robot("p3at"), BuildOptions())
        image, yaml_path = write_map(tmp_path / f"map{i}{suffix}", result.map, mode=mode)
        images.append((image.read_bytes(), yaml_path.read_text().replace(f"map{i}", "map")))
    assert images[0] == images[1]
    assert len(images[0][0]) > 1000  # a real map, not an empty file
