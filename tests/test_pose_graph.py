"""The pose graph (gtsam): a drifting square loop closed, a false closure held off by the kernel."""

from __future__ import annotations

import dataclasses
import itertools
import math
import mmap

import gtsam
import numpy as np
import pytest

from gridmap_cli.geometry import logmap
from gridmap_cli.poses.correction.correlative import LikelihoodGrid, search
from gridmap_cli.poses.correction.loop_closure import ClosureParams, candidates
from gridmap_cli.poses.correction.pose_graph import Edge, PoseGraph, edge_residuals
from gridmap_cli.poses.correction.slam import SlamParams, keyframes


def _square(n_side: int = 10, side_m: float = 10.0) -> np.ndarray:
    """A square loop driven counter-clockwise, ending back at the start: (4n+1, 3)."""
    poses = []
    step = side_m / n_side
    x = y = th = 0.0
    poses.append((x, y, th))
    for _ in range(4):
        for _ in range(n_side):
            x += step * math.cos(th)
            y += step * math.sin(th)
            poses.append((x, y, th))
        th += math.pi / 2
        poses[-1] = (x, y, th)
    return np.array(poses)


def _drifting_graph(truth: np.ndarray) -> PoseGraph:
    """Sequential edges from the truth with a heading drift of 1 degree per step."""
    edges = []
    est = [truth[0].copy()]
    for k in range(len(truth) - 1):
        a, b = truth[k], truth[k + 1]
        c, s = math.cos(a[2]), math.sin(a[2])
        dx = c * (b[0] - a[0]) + s * (b[1] - a[1])
        dy = -s * (b[0] - a[0]) + c * (b[1] - a[1])
        dth = b[2] - a[2] + math.radians(1.0)
        edges.append(Edge(k, k + 1, dx, dy, dth, 0.05, math.radians(1.0)))
        p = est[-1]
        cp, sp = math.cos(p[2]), math.sin(p[2])
        est.append(np.array([p[0] + cp * dx - sp * dy, p[1] + sp * dx + cp * dy, p[2] + dth]))
    return PoseGraph(np.array(est), edges)


def _error_m(poses: np.ndarray, truth: np.ndarray) -> float:
    return float(np.hypot(*(poses[:, :2] - truth[:, :2]).T).mean())


def _closure(i: int, j: int, truth: np.ndarray) -> Edge:
    a, b = truth[i], truth[j]
    c, s = math.cos(a[2]), math.sin(a[2])
    dx = c * (b[0] - a[0]) + s * (b[1] - a[1])
    dy = -s * (b[0] - a[0]) + c * (b[1] - a[1])
    dth = math.remainder(b[2] - a[2], 2 * math.pi)
    return Edge(i, j, dx, dy, dth, 0.05, math.radians(1.0), closure=True)


def test_a_closed_loop_removes_most_of_the_drift() -> None:
    truth = _square()
    graph = _drifting_graph(truth)
    drifted = _error_m(graph.initial, truth)
    end = len(truth) - 1
    graph.edges.append(_closure(end, 0, truth))
    graph.edges.append(_closure(end - 2, 2, truth))
    optimised = graph.optimise()
    assert drifted > 1.0
    assert _error_m(optimised, truth) < 0.25 * drifted
    assert edge_residuals(optimised, graph.edges[-2:])[:, 0].max() < 0.2


def test_a_false_closure_cannot_fold_the_loop() -> None:
    truth = _square()
    graph = _drifting_graph(truth)
    end = len(truth) - 1
    graph.edges += [_closure(end, 0, truth), _closure(end - 1, 1, truth),
                    _closure(end - 2, 2, truth)]  # fmt: skip
    honest = _error_m(graph.optimise(), truth)
    # a planted closure claiming the middle of the second side sits on the start
    false = _closure(15, 0, truth)
    graph.edges.append(Edge(15, 0, 0.0, 0.0, 0.0, false.sigma_xy_m, false.sigma_theta_rad, True))
    optimised = graph.optimise()
    assert _error_m(optimised, truth) < honest + 0.3
    # the consistency check sees it: its residual is far above the true closures'
    res = edge_residuals(optimised, graph.edges[-4:])
    assert res[3, 0] > 3.0 and res[:3, 0].max() < 0.3


def test_without_the_kernel_the_false_closure_folds_it() -> None:
    truth = _square()
    graph = _drifting_graph(truth)
    graph.cauchy_k = 1e6  # effectively Gaussian: the kernel is what protects the map
    end = len(truth) - 1
    graph.edges += [_closure(end, 0, truth), Edge(15, 0, 0.0, 0.0, 0.0, 0.05, 0.02, True)]
    assert _error_m(graph.optimise(), truth) > 1.0


def test_marginals_grow_away_from_the_anchor() -> None:
    truth = _square()
    graph = _drifting_graph(truth)
    cov = graph.marginals(graph.optimise())
    assert cov.shape == (len(truth), 3, 3)
    assert cov[0, 0, 0] < cov[10, 0, 0] < cov[20, 0, 0]


def test_candidates_are_near_in_space_and_far_along_the_path() -> None:
    truth = _square()
    pairs = candidates(truth, np.arange(len(truth)), ClosureParams(min_path_m=8.0))
    assert (40, 0) in pairs or (40, 1) in pairs
    assert all(i > j and i - j >= 8 for i, j in pairs)


def test_keyframes_keep_the_ends_and_space_the_rest() -> None:
    poses = np.column_stack([np.linspace(0, 10, 101), np.zeros(101), np.zeros(101)])
    nodes = keyframes(poses, SlamParams(keyframe_m=0.5))
    assert nodes[0] == 0 and nodes[-1] == 100 and len(nodes) == 21
    assert pytest.approx(np.diff(poses[nodes, 0]).min(), abs=1e-9) == 0.5


def _room_outline(step_m: float = 0.05) -> np.ndarray:
    """Wall points of an L-shaped room with a pillar: no symmetry that a match could confuse."""
    corners = [(0, 0), (8, 0), (8, 3), (4, 3), (4, 7), (0, 7), (0, 0)]
    walls = []
    for (x0, y0), (x1, y1) in itertools.pairwise(corners):
        n = max(2, int(math.hypot(x1 - x0, y1 - y0) / step_m))
        walls.append(np.column_stack([np.linspace(x0, x1, n), np.linspace(y0, y1, n)]))
    pillar = np.column_stack([np.full(20, 2.0), np.linspace(1.0, 2.0, 20)])
    return np.vstack([*walls, pillar])


def _moved_into(points: np.ndarray, pose: tuple[float, float, float]) -> np.ndarray:
    """``points`` (target frame) as seen from ``pose``: the source whose true pose it is."""
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    d = points - np.array([x, y])
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


def test_the_correlative_search_finds_a_pose_metres_and_degrees_off() -> None:
    target = _room_outline()
    truth = (2.3, -1.7, math.radians(9.0))
    source = _moved_into(target, truth)[::3]
    grid = LikelihoodGrid(target, 0.05, 0.05, 5, 4.0)
    found = search(grid, source, (0.0, 0.0, 0.0), 4.0, math.radians(15.0), math.radians(0.5), 0.5)
    assert found is not None and found.score > 0.7
    assert math.hypot(found.x_m - truth[0], found.y_m - truth[1]) < 0.08
    assert abs(found.theta_rad - truth[2]) < math.radians(0.6)


def test_branch_and_bound_gives_the_exhaustive_search_answer() -> None:
    target = _room_outline()
    source = _moved_into(target, (0.4, 0.3, math.radians(2.0)))[::4]
    grid = LikelihoodGrid(target, 0.1, 0.1, 3, 1.0)
    found = search(grid, source, (0.0, 0.0, 0.0), 1.0, math.radians(3.0), math.radians(1.0), 0.1)
    assert found is not None
    best = -1.0
    offsets = np.array([(u, v) for u in range(-10, 11) for v in range(-10, 11)])
    for k in range(-3, 4):
        th = math.radians(k)
        c, s = math.cos(th), math.sin(th)
        moved = np.column_stack([c * source[:, 0] - s * source[:, 1],
                                 s * source[:, 0] + c * source[:, 1]])  # fmt: skip
        best = max(best, float(grid.score(0, grid.cells(moved), grid.offsets(offsets)).max()))
    assert found.score == pytest.approx(best, abs=1e-6)


def test_the_correlative_search_finds_nothing_where_nothing_matches() -> None:
    target = _room_outline()
    rng = np.random.default_rng(3)
    clutter = rng.uniform(-20.0, -15.0, size=(200, 2))  # far from every wall
    grid = LikelihoodGrid(target, 0.1, 0.1, 4, 2.0)
    found = search(grid, clutter, (0.0, 0.0, 0.0), 2.0, math.radians(10.0), math.radians(1.0), 0.5)
    assert found is None


def test_the_closure_search_hands_the_heap_back_once_as_it_starts(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The scan matcher's freed scratch goes back when the search starts; the search grids
    live on pages of their own (they go back as each is let go), so no grid asks again."""
    from gridmap_cli.poses.correction import loop_closure
    from gridmap_cli.poses.correction.loop_closure import ClosureParams, Submaps

    calls: list[int] = []
    monkeypatch.setattr(loop_closure, "release_free_memory", lambda: calls.append(1) or True)
    rng = np.random.default_rng(0)
    n = 30
    points = [rng.uniform(-3.0, 3.0, (200, 2)) for _ in range(n)]
    local = np.column_stack([np.arange(n) * 0.5, np.zeros(n), np.zeros(n)])
    submaps = Submaps(points, local, np.arange(n), ClosureParams())
    assert len(calls) == 1
    for node in range(8 + 3):  # 8 kept, then one let go per new grid
        grid = submaps.grid(node)
    assert len(calls) == 1
    # each level a view of the grid's own mapping, not of a block from the heap
    assert all(isinstance(level.base, np.ndarray) for level in grid.flat)
    owner = grid.flat[0]
    while isinstance(owner.base, np.ndarray):
        owner = owner.base
    assert isinstance(owner.base, memoryview) and isinstance(owner.base.obj, mmap.mmap)


def test_the_edge_covariances_are_gtsams_joint_marginals() -> None:
    """The selected inverse gives each edge's joint covariance as gtsam's joint marginal of its
    two nodes does, on a loop with closures (robust), a corridor edge (a full covariance) and
    an edge drawn against the elimination order (j before i)."""
    truth = _square(6, 6.0)
    graph = _drifting_graph(truth)
    graph.edges[3] = dataclasses.replace(graph.edges[3], weak_sigma_m=0.4, weak_axis=(0.6, 0.8))
    graph.edges += [_closure(0, 24, truth), _closure(5, 17, truth), _closure(20, 2, truth)]
    poses = graph.optimise()
    values = gtsam.Values()
    for k, (x, y, th) in enumerate(poses):
        values.insert(k, gtsam.Pose2(float(x), float(y), float(th)))
    marginals = gtsam.Marginals(graph._factors(), values)
    ours = graph.edge_covariances(poses)
    for e, c in zip(graph.edges, ours, strict=True):
        joint = marginals.jointMarginalCovariance(gtsam.KeyVector([e.i, e.j]))
        want = np.block(
            [[joint.at(e.i, e.i), joint.at(e.i, e.j)], [joint.at(e.j, e.i), joint.at(e.j, e.j)]]
        )
        np.testing.assert_allclose(c, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())


def test_the_residual_budget_is_the_per_edge_sum_with_gtsams_marginals() -> None:
    """The budget, vectorised over the edges, against the sum edge by edge with gtsam's own
    Pose2 algebra and joint marginals, on a loop whose closures are bent (robust weights) and
    a corridor edge."""
    truth = _square(6, 6.0)
    graph = _drifting_graph(truth)
    graph.edges[3] = dataclasses.replace(graph.edges[3], weak_sigma_m=0.4, weak_axis=(0.6, 0.8))
    bent = dataclasses.replace(_closure(5, 17, truth), dx_m=_closure(5, 17, truth).dx_m + 0.3)
    graph.edges += [_closure(0, 24, truth), bent, _closure(20, 2, truth)]
    poses = graph.optimise()
    values = gtsam.Values()
    for k, (x, y, th) in enumerate(poses):
        values.insert(k, gtsam.Pose2(float(x), float(y), float(th)))
    marginals = gtsam.Marginals(graph._factors(), values)
    want = np.zeros((2, 2))
    for e in graph.edges:
        est = values.atPose2(e.i).between(values.atPose2(e.j))
        r = gtsam.Pose2.Logmap(gtsam.Pose2(e.dx_m, e.dy_m, e.dtheta_rad).between(est))
        info = np.linalg.inv(e.covariance())
        w = 1.0 / (1.0 + float(r @ info @ r) / graph.cauchy_k**2) if e.closure else 1.0
        joint = marginals.jointMarginalCovariance(gtsam.KeyVector([e.i, e.j]))
        c = np.block(
            [[joint.at(e.i, e.i), joint.at(e.i, e.j)], [joint.at(e.j, e.i), joint.at(e.j, e.j)]]
        )
        jac = np.hstack([-est.inverse().AdjointMap(), np.eye(3)])
        p = jac @ c @ jac.T
        want[0] += w * r[:2] @ info[:2, :2] @ r[:2], 2.0 - w * np.trace(info[:2, :2] @ p[:2, :2])
        want[1] += w * info[2, 2] * r[2] ** 2, 1.0 - w * info[2, 2] * p[2, 2]
    assert want[0, 0] > 1.0  # the bent closure shows
    np.testing.assert_allclose(graph.residual_budget(poses), want, rtol=1e-9)


def test_the_pose_logarithm_is_gtsams() -> None:
    rng = np.random.default_rng(3)
    poses = rng.normal(0.0, 2.0, (50, 3))
    poses[:, 2] = np.concatenate([rng.uniform(-3.1, 3.1, 45), [0.0, 1e-12, -1e-11, 1e-9, 3.14]])
    ours = np.column_stack(logmap(poses[:, 0], poses[:, 1], poses[:, 2]))
    for p, mine in zip(poses, ours, strict=True):
        np.testing.assert_allclose(mine, gtsam.Pose2.Logmap(gtsam.Pose2(*p)), atol=1e-12)
