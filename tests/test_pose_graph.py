"""The pose graph (gtsam): a drifting square loop closed, a false closure held off by the kernel."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gridmap_cli.poses.loop_closure import ClosureParams, candidates
from gridmap_cli.poses.pose_graph import Edge, PoseGraph, edge_residuals
from gridmap_cli.poses.slam import SlamParams, keyframes


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
