"""build --draw-path: a preview PNG beside the map, never the map_server image itself."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from gridmap_cli.mapping.grid import GridSpec, OccupancyMap
from gridmap_cli.records import PoseTrack
from gridmap_cli.writers.preview import (
    ODOMETRY_RGB,
    REFERENCE_RGB,
    SPREAD_RGB,
    UNKNOWN_RGB,
    drawn,
    placed_at,
    write_preview,
)
from tests.helpers import names, run

CSV = Path(__file__).resolve().parents[2] / "samples" / "corridor_loop.csv"


def pixels_of(image: np.ndarray, rgb: tuple[int, int, int]) -> int:
    return int(np.count_nonzero(np.all(image == np.array(rgb), axis=2)))


@pytest.mark.parametrize("pose", ["odometry", "global"])
def test_the_preview_draws_both_tracks_and_leaves_the_map_alone(tmp_path: Path, pose: str) -> None:
    plain, drawn = tmp_path / "plain", tmp_path / "drawn"
    plain.mkdir()
    drawn.mkdir()
    assert run("build", str(CSV), "-o", str(plain / "m.png"), "-q", "--pose", pose)[0] == 0
    code, _, err = run("build", str(CSV), "-o", str(drawn / "m.png"), "-q", "--pose", pose,
                       "--draw-path")  # fmt: skip
    assert code == 0, err
    assert names(drawn) == {"m.png", "m.yaml", "m_path.png"}
    for name in ("m.png", "m.yaml"):
        assert (plain / name).read_bytes() == (drawn / name).read_bytes()
    whole = np.asarray(Image.open(drawn / "m_path.png"))
    assert whole.shape[2] == 3
    # the map's pixels on top, row for row and column for column; the legend under them
    height, width = np.asarray(Image.open(drawn / "m.png")).shape[:2]
    assert whole.shape[0] > height and whole.shape[1] >= width
    preview = whole[:height, :width]
    legend = whole[height:]
    for rgb in (UNKNOWN_RGB, ODOMETRY_RGB, REFERENCE_RGB):  # a swatch of each colour used
        assert pixels_of(legend, rgb) >= 50
    assert pixels_of(legend, SPREAD_RGB) == 0  # no layer, no spread in the legend
    assert pixels_of(preview, UNKNOWN_RGB) > 1000  # unknown shows, not white
    assert pixels_of(preview, ODOMETRY_RGB) > 200
    assert pixels_of(preview, REFERENCE_RGB) > 200  # the CSV's true_* track


def test_an_existing_preview_is_not_overwritten_without_force(tmp_path: Path) -> None:
    (tmp_path / "m_path.png").write_bytes(b"keep")
    code, _, err = run("build", str(CSV), "-o", str(tmp_path / "m.png"), "--draw-path")
    assert code == 1 and "m_path.png exists (use --force to overwrite)" in err
    assert names(tmp_path) == {"m_path.png"}


def test_the_other_track_is_placed_by_the_first_common_pose() -> None:
    stamps = np.arange(4, dtype=np.int64) * 10
    anchor = PoseTrack.from_rows(stamps, [(1.0, 2.0, np.pi / 2)] * 4)
    track = PoseTrack.from_rows(stamps, [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (2, 0, 0), (3, 0, 0)])
    placed = placed_at(track, anchor, (0, 0, 0))
    assert placed is not None
    # turned by +90 degrees about (1, 2): x along the anchor's heading
    assert placed.x_m == pytest.approx([1.0, 1.0, 1.0, 1.0])
    assert placed.y_m == pytest.approx([2.0, 3.0, 4.0, 5.0])
    later = PoseTrack.from_rows(stamps + 100, [(0.0, 0.0, 0.0)] * 4)
    assert placed_at(later, anchor, (0, 0, 0)) is None  # no common time


def test_the_spread_tints_the_cells_and_enters_the_legend(tmp_path: Path) -> None:
    spec = GridSpec(0.0, 0.0, 0.1, 40, 20)
    omap = OccupancyMap(spec, np.full(spec.shape, 0.01))
    spread = np.zeros(spec.shape)
    spread[:, 20:] = 2.0  # the right half was seen from poses 2 m off
    # drawn below the map: the legend still names it
    track = drawn(PoseTrack.from_rows(np.arange(2, dtype=np.int64), [(0.0, -1.0, 0.0)] * 2),
                  ODOMETRY_RGB)  # fmt: skip
    path = write_preview(tmp_path / "p.png", omap, [track], spread)
    image = np.asarray(Image.open(path)).astype(int)
    left, right = image[:20, :20], image[:20, 20:40]
    assert (left == 252).all()  # free, untouched: grey round(255 * 0.99)
    # tinted towards orange: red stays high, blue falls
    assert (right[:, :, 0] > right[:, :, 2] + 100).all()
    assert pixels_of(image[20:], SPREAD_RGB) >= 50
