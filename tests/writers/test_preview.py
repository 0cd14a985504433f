"""build --draw-path: a preview PNG beside the map, never the map_server image itself."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from gridmap_cli.records import PoseTrack
from gridmap_cli.writers.preview import ODOMETRY_RGB, REFERENCE_RGB, UNKNOWN_RGB, placed_at
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
    preview = np.asarray(Image.open(drawn / "m_path.png"))
    assert preview.shape[2] == 3
    assert preview.shape[:2] == np.asarray(Image.open(drawn / "m.png")).shape[:2]
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
