"""The correlative search's likelihood grid: the cropped computation gives the whole grid's
values, and the search finds the pose a point set was moved by."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from gridmap_cli import extensions
from gridmap_cli.extensions import optional
from gridmap_cli.poses.correction.correlative import LikelihoodGrid, search


def _whole_grid(points: np.ndarray, res: float, sigma: float, levels: int, reach: float) -> list:
    """The grid and its pooled levels computed over every cell, the plain way."""
    pad = 2 * (2**levels + 2 + math.ceil(reach / res))
    low = points.min(axis=0) - pad * res
    high = points.max(axis=0) + pad * res
    shape = np.ceil((high - low) / res).astype(int) + 1
    cells = np.floor((points - low) / res).astype(int)
    hit = np.zeros(tuple(shape), dtype=bool)
    hit[cells[:, 0], cells[:, 1]] = True
    dist = ndimage.distance_transform_edt(~hit) * res
    base = np.exp(-0.5 * (dist / sigma) ** 2).astype(np.float32)
    base[:pad, :] = base[-pad:, :] = 0.0
    base[:, :pad] = base[:, -pad:] = 0.0
    grids = [base]
    for level in range(levels):
        g, h = grids[-1], 2**level
        up = g.copy()
        up[:-h, :] = np.maximum(up[:-h, :], g[h:, :])
        up2 = up.copy()
        up2[:, :-h] = np.maximum(up2[:, :-h], up[:, h:])
        grids.append(up2)
    return [g.ravel() for g in grids]


def test_cropped_grid_equals_the_whole_grid() -> None:
    rng = np.random.default_rng(3)
    for trial in range(40):
        n = int(rng.integers(1, 800))
        if trial % 2:  # a wall, dense along a line
            along = rng.uniform(0, 12, n)
            a = rng.uniform(0, math.pi)
            points = np.column_stack([along * math.cos(a), along * math.sin(a)])
        else:
            points = rng.uniform(-8, 8, (n, 2))
        points = points + rng.uniform(-50, 50, 2)
        res, levels, reach = (0.1, 0.05)[trial % 2], int(rng.integers(1, 6)), rng.uniform(0.2, 6)
        grid = LikelihoodGrid(points, res, 0.1, levels, reach)
        for got, want in zip(grid.flat, _whole_grid(points, res, 0.1, levels, reach), strict=True):
            assert got.dtype == np.float32
            assert np.array_equal(got, want)


def test_levels_and_grids_hold_memory_of_their_own() -> None:
    """The levels are cut from one block of fresh pages: none may overlap another, nor a
    second grid's, and each outlives the grid object that made it."""
    rng = np.random.default_rng(5)
    a = LikelihoodGrid(rng.uniform(-5, 5, (300, 2)), 0.1, 0.1, 4, 2.0)
    b = LikelihoodGrid(rng.uniform(-5, 5, (300, 2)), 0.1, 0.1, 4, 2.0)
    arrays = a.flat + b.flat
    for k, one in enumerate(arrays):
        assert one.flags.writeable
        for other in arrays[k + 1 :]:
            assert not np.shares_memory(one, other)
    kept = a.flat[2]
    copy = kept.copy()
    del a
    assert np.array_equal(kept, copy)


def test_search_finds_the_offset() -> None:
    rng = np.random.default_rng(4)
    walls = [np.column_stack([rng.uniform(-5, 5, 300), np.full(300, y)]) for y in (-3.0, 4.0)]
    walls.append(np.column_stack([np.full(300, 6.0), rng.uniform(-3, 4, 300)]))
    target = np.vstack(walls)
    grid = LikelihoodGrid(target, 0.1, 0.1, 5, 6.0)
    true = (1.3, -0.8, math.radians(7.0))
    c, s = math.cos(true[2]), math.sin(true[2])
    # the source: the target seen from the true pose
    shifted = target - np.array(true[:2])
    source = np.column_stack(
        [c * shifted[:, 0] + s * shifted[:, 1], -s * shifted[:, 0] + c * shifted[:, 1]]
    )[::3]
    found = search(grid, source, (0.0, 0.0, 0.0), 2.0, math.radians(15), math.radians(1), 0.5)
    assert found is not None
    assert abs(found.x_m - true[0]) <= 0.1 and abs(found.y_m - true[1]) <= 0.1
    assert abs(found.theta_rad - true[2]) <= math.radians(1.01)
    assert found.score > 0.8


@pytest.mark.parametrize("vectors", [True, False], ids=["vector sums", "scalar sums"])
def test_compiled_search_equals_the_numpy_one(
    monkeypatch: pytest.MonkeyPatch, vectors: bool
) -> None:
    """The compiled branch and bound returns the numpy reference's pose and score bit for bit,
    ties included (targets and sources on a lattice give tied scores), with its sums in
    vectors where the processor has them and without."""
    compiled_module = optional("gridmap_cli.poses.correction._cbranch")
    if compiled_module is None:
        pytest.skip("the compiled branch and bound is not built")
    try:
        if compiled_module.vectors(vectors) != vectors:
            pytest.skip("this processor has no AVX2")
        _compare_searches(monkeypatch)
    finally:
        compiled_module.vectors(True)


def _compare_searches(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(5)
    outcomes = set()
    for trial in range(40):
        walls = []
        for _ in range(int(rng.integers(1, 5))):
            a, along = rng.uniform(0, math.pi), rng.uniform(-8, 8, 200)
            o = rng.uniform(-4, 4, 2)
            walls.append(np.column_stack([o[0] + along * math.cos(a), o[1] + along * math.sin(a)]))
        target = np.vstack(walls) + rng.normal(0, 0.02, (len(walls) * 200, 2))
        k = int(rng.integers(5, 400))
        source = target[rng.integers(0, len(target), k)] + rng.normal(0, 0.05, (k, 2))
        if trial % 3 == 0:
            target, source = np.round(target, 1), np.round(source, 1)
        grid = LikelihoodGrid(target, 0.1, 0.1, 5, 6.0)
        guess = (rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-0.2, 0.2))
        args = (guess, rng.uniform(0.5, 6), math.radians(15), math.radians(1))
        min_score = rng.uniform(0.3, 0.95)
        compiled = search(grid, source, *args, min_score)
        monkeypatch.setattr(extensions, "KERNELS", "numpy")
        reference = search(grid, source, *args, min_score)
        monkeypatch.setattr(extensions, "KERNELS", "auto")
        assert compiled == reference
        outcomes.add(reference is None)
    assert outcomes == {True, False}  # both a pose found and none above the floor were checked
