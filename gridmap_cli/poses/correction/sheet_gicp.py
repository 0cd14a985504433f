"""Planar point sets as small_gicp takes them: poses as its 4 x 4 transforms, scans lifted to a thin
sheet (:func:`planar_sheet`), and GICP of such sheets without the lift.

small_gicp registers in 3-D. The closure search hands it each submap as a thin sheet: every
planar point at three heights one layer apart (the layer the voxel size, so the copies keep to
their own voxels), so that a wall becomes a vertical plane and clutter a mix of planes. Each copy
takes the covariance of its 10 nearest copies, regularised as a plane (variance 1 in it, 1e-3
along its normal), and GICP weighs each residual by the inverse of the two copies' covariances
summed. That takes three kd-tree queries per point where one would do:

- a copy's nearest copies are copies of the point's nearest planar points (a copy of a farther
  point is farther on every layer), so one planar query gives the neighbours of all three
  copies;
- a source copy's nearest target copy is the planar nearest target point on the nearest target
  layer, so one planar query per source point finds the correspondences of all three.

The compiled kernel (``_csheet.c``) computes the sheet's covariances and its registration that
way, in the plane, with small_gicp's Levenberg-Marquardt steps and convergence on the turn and
shift in the plane (the sheet's symmetry holds small_gicp's height, roll and pitch near zero).
Where it is not built, small_gicp runs on the sheet itself. The covariances agree to rounding
but where a copy's tenth and eleventh nearest copies are equally far (the layers mirror each
other), which one a kd-tree keeps being its own choice: a few percent of them differ there. A
registration lands within the millimetres that small_gicp's convergence leaves between two
starts (``tests/test_sheet_gicp.py`` holds both to small_gicp).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import small_gicp
from scipy.spatial import cKDTree

from gridmap_cli.extensions import optional

FloatArray = npt.NDArray[np.float64]
Pose = tuple[float, float, float]


def pose_matrix(x: float, y: float, theta: float) -> FloatArray:
    """The planar pose as the 4 x 4 transform small_gicp takes."""
    m = np.eye(4)
    c, s = math.cos(theta), math.sin(theta)
    m[0, 0], m[0, 1], m[1, 0], m[1, 1] = c, -s, s, c
    m[0, 3], m[1, 3] = x, y
    return m


def planar_pose(m: FloatArray) -> tuple[float, float, float]:
    """The planar pose (x, y, theta) of a 4 x 4 transform."""
    return float(m[0, 3]), float(m[1, 3]), math.atan2(float(m[1, 0]), float(m[0, 0]))


def placed_points(points: FloatArray, pose: tuple[float, float, float]) -> FloatArray:
    """Points (K, 2) of a scan moved to ``pose`` (x, y, theta)."""
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    return np.column_stack(
        [x + c * points[:, 0] - s * points[:, 1], y + s * points[:, 0] + c * points[:, 1]]
    )


def planar_sheet(points: FloatArray, voxel_m: float) -> FloatArray:
    """Planar points (K, 2) as three layers one voxel apart in z, shape (3K, 3)."""
    k = len(points)
    sheet = np.empty((3 * k, 3))
    for layer, z in enumerate((-voxel_m, 0.0, voxel_m)):
        # the layers filled in place (this runs for every scan and local map); + 0.0 as a sum
        # with the lift vector has it: a -0.0 coordinate becomes +0.0
        np.add(points, 0.0, out=sheet[layer * k : (layer + 1) * k, :2])
        sheet[layer * k : (layer + 1) * k, 2] = z + 0.5 * voxel_m
    return sheet


def sheet_cloud(
    points: FloatArray, voxel_m: float
) -> tuple[small_gicp.PointCloud, small_gicp.KdTree]:
    """Planar points (K, 2) as small_gicp's sheet (:func:`planar_sheet`) downsampled to
    ``voxel_m``, each copy's covariance from its 10 nearest, and the sheet's kd-tree."""
    cloud, tree = small_gicp.preprocess_points(
        planar_sheet(points, voxel_m), downsampling_resolution=voxel_m, num_neighbors=10
    )
    return cloud, tree


def register(
    target: small_gicp.PointCloud,
    tree: small_gicp.KdTree,
    source: small_gicp.PointCloud,
    start: Pose,
    max_distance_m: float,
    max_iterations: int,
) -> tuple[Pose, FloatArray]:
    """small_gicp's GICP (one thread) of the sheet ``source`` onto ``target`` from the planar
    pose ``start``: the planar pose found and GICP's Hessian (6, 6)."""
    result = small_gicp.align(
        target,
        source,
        tree,
        init_T_target_source=pose_matrix(*start),
        registration_type="GICP",
        max_correspondence_distance=max_distance_m,
        max_iterations=max_iterations,
        num_threads=1,
    )
    return planar_pose(np.asarray(result.T_target_source)), np.asarray(result.H)


#: The nearest copies a copy's covariance is taken from (itself included), as the closure search
#: has small_gicp take them.
NEIGHBOURS = 10

_NAME = "gridmap_cli.poses.correction._csheet"


@dataclass(frozen=True)
class Sheet:
    """A planar point set ready to register: ``points`` (K, 2), the voxels' means, each once, and
    ``layer_m``, the sheet's layer spacing. Compiled: ``dims`` the implicit kd-tree's split axes
    (``points`` in its order) and ``covs`` (K, 3, 6) each copy's covariance (xx xy xz yy yz zz),
    lowest layer first. Reference: small_gicp's ``cloud`` and ``tree`` of the sheet, and
    ``index``, a planar tree of ``points``."""

    points: FloatArray
    layer_m: float
    dims: npt.NDArray[np.uint8] | None = None
    covs: FloatArray | None = None
    cloud: small_gicp.PointCloud | None = None
    tree: small_gicp.KdTree | None = None
    index: cKDTree | None = None

    def __len__(self) -> int:
        return int(self.points.shape[0])


@dataclass(frozen=True)
class Registration:
    """The source's pose in the target's frame (x, y, theta) and the Hessian of the last
    linearisation over the shift in the plane (2, 2), in the source's frame."""

    pose: Pose
    hessian_xy: FloatArray


def sheet_of(points: FloatArray, voxel_m: float) -> Sheet:
    """The planar points (K, 2) downsampled to ``voxel_m``, as a sheet of layers that far apart."""
    compiled = optional(_NAME)
    if compiled is None:
        cloud, tree = small_gicp.preprocess_points(
            lifted(points, voxel_m), downsampling_resolution=voxel_m, num_neighbors=NEIGHBOURS
        )
        xy = np.asarray(cloud.points())[:, :2]
        # a row as one complex number: numpy's 1D unique is several times its row unique
        rows = np.unique(np.ascontiguousarray(xy).view(np.complex128).ravel())
        flat = np.ascontiguousarray(rows.view(np.float64).reshape(-1, 2))
        return Sheet(flat, voxel_m, cloud=cloud, tree=tree, index=cKDTree(flat))
    flat = voxel_means(points, voxel_m)
    n = len(flat)
    order = np.empty(n, dtype=np.int64)
    dims = np.empty(n, dtype=np.uint8)
    compiled.kdtree(flat, order, dims)
    ordered = np.ascontiguousarray(flat[order])
    covs = np.empty((n, 3, 6))
    compiled.sheet_covariances(ordered, dims, NEIGHBOURS, voxel_m, covs)
    return Sheet(ordered, voxel_m, dims=dims, covs=covs)


def lifted(points: FloatArray, layer_m: float) -> FloatArray:
    """Planar points (K, 2) as three layers at heights -``layer_m``, 0 and ``layer_m``, (3K, 3)."""
    k = len(points)
    sheet = np.empty((3 * k, 3))
    for layer, z in enumerate((-layer_m, 0.0, layer_m)):
        sheet[layer * k : (layer + 1) * k, :2] = points
        sheet[layer * k : (layer + 1) * k, 2] = z
    return sheet


def voxel_means(points: FloatArray, voxel_m: float) -> FloatArray:
    """The mean of the points (K, 2) in each ``voxel_m`` square (V, 2): the squares as
    small_gicp's voxel grid cuts them (the coordinates times the inverse of the size, floored)."""
    if len(points) == 0:
        return np.zeros((0, 2))
    cells = np.floor(points * (1.0 / voxel_m)).astype(np.int64)
    key = (cells[:, 0] << 32) + cells[:, 1]
    unique, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    sx = np.bincount(inverse, weights=points[:, 0], minlength=len(unique))
    sy = np.bincount(inverse, weights=points[:, 1], minlength=len(unique))
    return np.ascontiguousarray(np.column_stack([sx / counts, sy / counts]))


def align(
    target: Sheet, source: Sheet, start: Pose, max_distance_m: float, max_iterations: int
) -> Registration:
    """GICP of ``source`` onto ``target`` from ``start`` (the source's pose in the target's
    frame), small_gicp's convergence (a step under 0.1 degree and 1 mm)."""
    if target.covs is not None and source.covs is not None:
        compiled = optional(_NAME)
        assert compiled is not None
        pose = np.array(start, dtype=np.float64)
        hessian = np.empty(9)
        compiled.align_sheet(
            target.points, target.dims, target.covs, target.layer_m, source.points, source.covs,
            source.layer_m, pose, max_distance_m, max_iterations, math.radians(0.1), 1e-3,
            hessian,
        )  # fmt: skip
        xy = np.ascontiguousarray(hessian.reshape(3, 3)[1:3, 1:3])
        return Registration((float(pose[0]), float(pose[1]), float(pose[2])), xy)
    assert target.cloud is not None and target.tree is not None and source.cloud is not None
    found, hessian = register(
        target.cloud, target.tree, source.cloud, start, max_distance_m, max_iterations
    )
    return Registration(found, np.ascontiguousarray(hessian[3:5, 3:5]))


def nearest_m(sheet: Sheet, queries: FloatArray, radius_m: float) -> FloatArray:
    """The distance (Q,) from each query point (Q, 2) to the sheet's nearest planar point within
    ``radius_m``, inf where none is."""
    queries = np.ascontiguousarray(queries, dtype=np.float64).reshape(-1, 2)
    if sheet.dims is not None:
        compiled = optional(_NAME)
        assert compiled is not None
        out = np.empty(len(queries))
        compiled.nearest(sheet.points, sheet.dims, queries, radius_m, out)
        return out
    assert sheet.index is not None
    dist, _ = sheet.index.query(queries, distance_upper_bound=np.nextafter(radius_m, np.inf))
    return np.asarray(dist, dtype=np.float64)
