"""The compiled sheet GICP against small_gicp on the sheet itself, which it stands in for."""

from __future__ import annotations

import math

import numpy as np
import pytest
import small_gicp
from scipy.spatial import cKDTree

from gridmap_cli import extensions
from gridmap_cli.poses.correction import sheet_gicp
from gridmap_cli.poses.correction.sheet_gicp import align, lifted, nearest_m, sheet_of, voxel_means


@pytest.fixture
def compiled(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(extensions, "KERNELS", "compiled")


def _scene(seed: int) -> np.ndarray:
    """Two walls at a right angle, a third across a corner, and scattered clutter."""
    rng = np.random.default_rng(seed)
    t = rng.uniform(0.0, 10.0, 1500)
    walls = np.concatenate(
        [
            np.column_stack([t[:600], np.zeros(600)]),
            np.column_stack([np.full(600, 3.0), t[600:1200] - 5.0]),
            np.column_stack([t[1200:] * 0.3, 2.0 + t[1200:] * 0.3]),
        ]
    )
    clutter = rng.uniform(-2.0, 8.0, (300, 2))
    return np.vstack([walls + rng.normal(0.0, 0.01, walls.shape), clutter])


def _moved(points: np.ndarray, pose: tuple[float, float, float]) -> np.ndarray:
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    return points @ np.array([[c, s], [-s, c]]) + (x, y)


@pytest.mark.parametrize("voxel_m", [0.1, 0.2])
def test_the_covariances_are_small_gicps_of_the_lifted_sheet(
    compiled: None, voxel_m: float
) -> None:
    points = _scene(1)
    sheet = sheet_of(points, voxel_m)
    assert sheet.covs is not None and sheet.covs.shape == (len(sheet), 3, 6)
    cloud, _ = small_gicp.preprocess_points(
        lifted(points, voxel_m), downsampling_resolution=voxel_m, num_neighbors=10
    )
    xyz = np.asarray(cloud.points())[:, :3]
    theirs = np.array(cloud.covs())[:, :3, :3]
    # each of small_gicp's copies against the copy of the same voxel on the same layer
    dist, row = cKDTree(sheet.points).query(xyz[:, :2])
    layer = np.rint(xyz[:, 2] / voxel_m).astype(int) + 1
    six = sheet.covs[row, layer]
    ours = np.stack([six[:, [0, 1, 2]], six[:, [1, 3, 4]], six[:, [2, 4, 5]]], axis=1)
    same = (dist < 1e-9) & (np.abs(ours - theirs).max(axis=(1, 2)) < 1e-9)
    # the rest: a tenth nearest copy tied with an eleventh (the layers mirror each other), which
    # each kd-tree breaks its own way, and a voxel small_gicp splits in two
    assert same.mean() > 0.9
    # every covariance a plane: variance 1e-3 along its normal, 1 in it
    values = np.linalg.eigvalsh(ours)
    assert np.allclose(values, [1e-3, 1.0, 1.0])


def test_the_voxels_are_small_gicps(compiled: None) -> None:
    rng = np.random.default_rng(2)
    points = rng.uniform(-20.0, 30.0, (4000, 2))
    for voxel_m in (0.1, 0.2, 0.3):
        ours = voxel_means(points, voxel_m)
        theirs = np.asarray(
            small_gicp.voxelgrid_sampling(lifted(points, voxel_m), voxel_m).points()
        )
        middle = theirs[np.abs(theirs[:, 2]) < voxel_m / 4, :2]
        assert len(middle) == len(ours)
        dist, _ = cKDTree(ours).query(middle)
        assert dist.max() < 1e-12


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_registration_lands_where_small_gicps_does(
    monkeypatch: pytest.MonkeyPatch, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    target = _scene(seed)
    truth = (0.3, -0.2, math.radians(-3.0))
    # the source: a subset of the scene, seen from the truth pose, noisy
    picked = target[rng.permutation(len(target))[:1200]]
    x, y, th = truth
    c, s = math.cos(th), math.sin(th)
    local = (picked - (x, y)) @ np.array([[c, -s], [s, c]])
    source = local + rng.normal(0.0, 0.01, local.shape)
    for start in [(0.0, 0.0, 0.0), (0.6, 0.3, 0.1), (-0.3, 0.5, -0.15)]:
        monkeypatch.setattr(extensions, "KERNELS", "compiled")
        ours = align(sheet_of(target, 0.1), sheet_of(source, 0.2), start, 0.8, 30)
        monkeypatch.setattr(extensions, "KERNELS", "numpy")
        t, src = sheet_of(target, 0.1), sheet_of(source, 0.2)
        assert t.cloud is not None and t.covs is None
        theirs = align(t, src, start, 0.8, 30)
        # within what the convergence leaves (a last step under 1 mm and 0.1 degree: small_gicp
        # itself ends up to 3 mm apart from these starts)
        assert math.hypot(ours.pose[0] - theirs.pose[0], ours.pose[1] - theirs.pose[1]) < 5e-3
        assert abs(ours.pose[2] - theirs.pose[2]) < math.radians(0.05)
        # and both at the truth
        assert math.hypot(ours.pose[0] - truth[0], ours.pose[1] - truth[1]) < 0.01
        # the shift's Hessian: the same constraint, to the few covariances that differ
        ratio = np.linalg.eigvalsh(ours.hessian_xy) / np.linalg.eigvalsh(theirs.hessian_xy)
        assert np.all(np.abs(ratio - 1.0) < 0.05)


def test_a_corridor_holds_across_it_and_not_along_it(compiled: None) -> None:
    # two parallel walls: the Hessian of the shift pins the pose across the corridor only
    t = np.linspace(0.0, 20.0, 400)
    walls = np.vstack(
        [np.column_stack([t, np.full_like(t, -1.0)]), np.column_stack([t, np.ones_like(t)])]
    )
    sheet = sheet_of(walls, 0.1)
    result = align(sheet, sheet_of(walls[::2], 0.2), (0.0, 0.05, 0.0), 0.8, 30)
    values, vectors = np.linalg.eigh(result.hessian_xy)
    assert values[0] / values[1] < 1e-2
    assert abs(vectors[0, 0]) > 0.99  # the weak direction is along the corridor (x)
    assert abs(result.pose[1]) < 1e-3


@pytest.mark.parametrize("kernels", ["compiled", "numpy"])
def test_the_nearest_distances_are_a_trees(monkeypatch: pytest.MonkeyPatch, kernels: str) -> None:
    monkeypatch.setattr(extensions, "KERNELS", kernels)
    rng = np.random.default_rng(4)
    points = _scene(4)
    sheet = sheet_of(points, 0.1)
    assert (sheet.dims is None) == (kernels == "numpy")
    queries = rng.uniform(-3.0, 9.0, (500, 2))
    ours = nearest_m(sheet, queries, 0.3)
    dist, _ = cKDTree(sheet.points).query(queries, distance_upper_bound=0.3)
    assert np.array_equal(np.isfinite(ours), np.isfinite(dist))
    assert np.isfinite(ours).any() and not np.isfinite(ours).all()
    assert np.allclose(ours[np.isfinite(ours)], dist[np.isfinite(dist)])


def test_bad_shapes_are_refused(compiled: None) -> None:
    kernel = extensions.optional(sheet_gicp._NAME)
    assert kernel is not None
    sheet = sheet_of(_scene(5), 0.1)
    assert sheet.covs is not None and sheet.dims is not None
    with pytest.raises(ValueError, match="sheet_covariances"):
        kernel.sheet_covariances(sheet.points, sheet.dims, 10, 0.1, np.empty((len(sheet), 3, 5)))
    with pytest.raises(ValueError, match="k must be"):
        kernel.sheet_covariances(sheet.points, sheet.dims, 0, 0.1, np.empty((len(sheet), 3, 6)))
    with pytest.raises(ValueError, match="align_sheet"):
        kernel.align_sheet(
            sheet.points, sheet.dims, sheet.covs[:-1], 0.1, sheet.points, sheet.covs, 0.1,
            np.zeros(3), 0.8, 30, 1e-3, 1e-3, np.empty(9),
        )  # fmt: skip
