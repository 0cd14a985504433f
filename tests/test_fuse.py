"""``gridmap build --fuse``: several runs of one place into one map, evidence added in an order
that does not matter, to the byte."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gridmap_cli.mapping.grid import GridSpec
from gridmap_cli.records import PoseTrack
from gridmap_cli.runs.build import move_track as place
from gridmap_cli.runs.fuse import Partial, combine, reduce_tree, tree_pairs, union_spec
from tests.helpers import run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
RUNS = [str(SAMPLES / n) for n in ("corridor_loop.csv", "hall.csv", "office.csv")]


def build(tmp_path: Path, name: str, *args: str) -> bytes:
    out = tmp_path / f"{name}.png"
    code, _, err = run("build", *args, "-o", str(out), "-q")
    assert code == 0, err
    return out.read_bytes()


def test_the_order_of_the_logs_does_not_matter(tmp_path: Path) -> None:
    fused = [
        build(tmp_path, f"f{i}", *order, "--fuse", "--pose", "global")
        for i, order in enumerate([RUNS, RUNS[::-1], [RUNS[1], RUNS[0], RUNS[2]]])
    ]
    assert fused[0] == fused[1] == fused[2]
    assert build(tmp_path, "j", *RUNS, "--fuse", "--pose", "global", "--jobs", "3") == fused[0]


def test_one_log_fused_is_that_log_built(tmp_path: Path) -> None:
    plain = build(tmp_path, "plain", RUNS[1], "--pose", "global")
    assert build(tmp_path, "fused", RUNS[1], "--pose", "global", "--fuse") == plain


def test_initial_poses_place_each_log(tmp_path: Path) -> None:
    # the ARIA and CSV logs of one run, both placed at the run's true start: one map, twice
    # the evidence, the same extent as the run's own map
    logs = [str(SAMPLES / "corridor_loop.csv"), str(SAMPLES / "corridor_loop.2d")]
    out = tmp_path / "both.png"
    code, _, err = run("build", *logs, "-o", str(out), "--fuse", "--json", "-q",
                       "--initial-pose", "2,2,0", "--initial-pose", "2,2,0")  # fmt: skip
    assert code == 0, err
    one = tmp_path / "one.png"
    run("build", logs[0], "-o", str(one), "--fuse", "-q", "--initial-pose", "2,2,0")
    yaml_both = (tmp_path / "both.yaml").read_text().replace("both.png", "x")
    assert yaml_both == (tmp_path / "one.yaml").read_text().replace("one.png", "x")


@pytest.mark.parametrize(
    ("args", "text"),
    [
        ((RUNS[0], RUNS[1], "--fuse"), "--fuse needs the logs in one frame"),
        ((RUNS[0], RUNS[1], "--fuse", "--initial-pose", "0,0,0"), "got 1 for 2 logs"),
        ((RUNS[0], "--initial-pose", "0,0,0"), "--initial-pose: only with --fuse"),
        ((RUNS[0], "--fuse", "--initial-pose", "0,zero,0"), "expected X,Y,YAW_DEG"),
        ((RUNS[0], RUNS[0], "--fuse", "--pose", "global"), "same log content twice"),
        ((RUNS[0], "--fuse", "--pose", "global", "--executor", "dask"), "--scheduler ADDRESS"),
        ((RUNS[0], "--pose", "global", "--fuse", "--initial-pose", "0,0,0"), "--pose global"),
    ],
)
def test_fuse_usage_errors(tmp_path: Path, args: tuple[str, ...], text: str) -> None:
    code, _, err = run("build", *args, "-o", str(tmp_path / "m.png"))
    assert code == 2 and err.count("\n") == 1 and text in err, err
    assert not (tmp_path / "m.png").exists()


def test_place_moves_the_first_pose_and_keeps_the_shape() -> None:
    track = PoseTrack(
        stamp_ns=np.array([0, 1, 2], dtype=np.int64),
        x_m=np.array([1.0, 2.0, 2.0]),
        y_m=np.array([1.0, 1.0, 2.0]),
        theta_rad=np.array([0.0, 0.0, math.pi / 2]),
    )
    moved = place(track, (10.0, 5.0, math.pi / 2))
    np.testing.assert_allclose([moved.x_m[0], moved.y_m[0], moved.theta_rad[0]],
                               [10.0, 5.0, math.pi / 2], atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(moved.x_m, [10.0, 10.0, 9.0], atol=1e-12)
    np.testing.assert_allclose(moved.y_m, [5.0, 6.0, 6.0], atol=1e-12)


def partial(x0: int, y0: int, w: int, h: int, value: float, key: str) -> Partial:
    spec = GridSpec(round(x0 * 0.05, 9), round(y0 * 0.05, 9), 0.05, w, h)
    return Partial(spec, np.full((h, w), value), np.ones((h, w), dtype=np.int64), (key,), w * h)


@given(
    st.lists(
        st.tuples(st.integers(-20, 20), st.integers(-20, 20), st.integers(1, 6),
                  st.integers(1, 6), st.floats(-3, 3)),
        min_size=1, max_size=7,
    )
)  # fmt: skip
def test_combining_partials_places_them_at_whole_cells(
    boxes: list[tuple[int, int, int, int, float]],
) -> None:
    parts = [partial(*box, key=f"{i:02d}") for i, box in enumerate(boxes)]
    total = reduce_tree(parts)
    spec = total.spec
    expected_counts = np.zeros(spec.shape, dtype=np.int64)
    for x0, y0, w, h, _ in boxes:
        r = y0 - round(spec.origin_y_m / 0.05)
        c = x0 - round(spec.origin_x_m / 0.05)
        expected_counts[r : r + h, c : c + w] += 1
    np.testing.assert_array_equal(total.counts, expected_counts)
    assert total.keys == tuple(f"{i:02d}" for i in range(len(boxes)))
    assert spec.width == max(b[0] + b[2] for b in boxes) - min(b[0] for b in boxes)


def test_tree_pairs() -> None:
    assert tree_pairs(1) == []
    assert tree_pairs(4) == [[(0, 1), (2, 3)], [(0, 1)]]
    assert tree_pairs(5) == [[(0, 1), (2, 3)], [(0, 1)], [(0, 1)]]


def test_union_spec_of_other_resolutions_is_refused() -> None:
    from gridmap_cli.errors import GridmapError

    with pytest.raises(GridmapError):
        union_spec(GridSpec(0, 0, 0.05, 2, 2), GridSpec(0, 0, 0.1, 2, 2))
    a = partial(0, 0, 2, 2, 1.0, "a")
    assert combine(a, partial(4, 0, 1, 1, 2.0, "b")).spec.width == 5
