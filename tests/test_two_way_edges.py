"""Two-way edges: a step whose scan match and odometry disagree far beyond the log's usual
keeps both ends, and the rest of the graph chooses between them."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from gridmap_cli.poses.correction.degeneracy import second_ends
from gridmap_cli.poses.correction.pose_graph import Edge, PoseGraph

STEP_M = 0.5
SLID = 10  # the step whose scan match slid


def _drive(n: int = 20, side: int = 10) -> np.ndarray:
    """A drive of ``n`` steps of STEP_M, turning left by 90 degrees every ``side`` steps."""
    poses = [(0.0, 0.0, 0.0)]
    for k in range(1, n + 1):
        x, y, th = poses[-1]
        x, y = x + STEP_M * math.cos(th), y + STEP_M * math.sin(th)
        if k % side == 0:
            th += math.pi / 2
        poses.append((x, y, th))
    return np.array(poses)


def _rel(poses: np.ndarray, i: int, j: int) -> tuple[float, float, float]:
    a, b = poses[i], poses[j]
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return c * dx + s * dy, -s * dx + c * dy, math.remainder(b[2] - a[2], 2 * math.pi)


def _chain(truth: np.ndarray, slide_m: float, two_way: bool) -> PoseGraph:
    """Sequential edges from ``truth``, the step into node SLID + 1 slid ``slide_m`` on along
    the travel (the scan's end), its odometry end the true one; ``two_way``: that edge keeps
    both."""
    edges = []
    for k in range(len(truth) - 1):
        dx, dy, dth = _rel(truth, k, k + 1)
        other = None
        if k == SLID:
            other = (dx, dy) if two_way else None
            dx += slide_m
        edges.append(Edge(k, k + 1, dx, dy, dth, 0.02, math.radians(0.5), other=other))
    start = [truth[0]]
    for e in edges:
        x, y, th = start[-1]
        c, s = math.cos(th), math.sin(th)
        start.append((x + c * e.dx_m - s * e.dy_m, y + s * e.dx_m + c * e.dy_m, th + e.dtheta_rad))
    return PoseGraph(np.array(start), edges)


def _closure(truth: np.ndarray, i: int, j: int, sigma_m: float = 0.05) -> Edge:
    return Edge(i, j, *_rel(truth, i, j), sigma_m, math.radians(1.0), closure=True)


def _error_m(poses: np.ndarray, truth: np.ndarray) -> float:
    return float(np.hypot(*(poses[:, :2] - truth[:, :2]).T).max())


def test_only_steps_that_miss_the_odometry_far_beyond_the_usual_get_a_second_end() -> None:
    truth = _drive(40)
    rng = np.random.default_rng(0)
    odometry = truth.copy()
    # the odometry's usual miss: a few millimetres per step, walked
    odometry[1:, :2] += np.cumsum(rng.normal(0.0, 0.003, (len(truth) - 1, 2)), axis=0)
    matched = truth.copy()
    matched[SLID + 1 :, 0] += 0.3  # one scan match slid 0.3 m; the rest follows it
    nodes = np.arange(len(truth))
    ends = second_ends(matched, odometry, nodes, 1.0)
    assert len(ends) == len(truth) - 1
    assert [k for k, e in enumerate(ends) if e is not None] == [SLID]
    odo_step = _rel(odometry, SLID, SLID + 1)
    assert np.allclose(ends[SLID], odo_step[:2])
    # the odometry's end is taken with its learned distance scale
    scaled = second_ends(matched, odometry, nodes, 1.02)[SLID]
    assert scaled is not None and np.allclose(scaled, 1.02 * np.array(odo_step[:2]))


def test_a_log_whose_matches_mostly_are_its_odometry_has_no_yardstick_for_a_miss() -> None:
    # most scans fell back to the odometry (a miss of 0); one step slid 0.3 m: with a median
    # miss of 0 every miss would be "far beyond the usual", so none is doubted
    truth = _drive(30)
    matched = truth.copy()
    matched[SLID + 1 :, 0] += 0.3
    assert second_ends(matched, truth.copy(), np.arange(len(truth)), 1.0) == [None] * 30
    # with a usual miss to measure against, the same slide is doubted
    rng = np.random.default_rng(1)
    odometry = truth.copy()
    odometry[1:, :2] += np.cumsum(rng.normal(0.0, 0.003, (len(truth) - 1, 2)), axis=0)
    ends = second_ends(matched, odometry, np.arange(len(truth)), 1.0)
    assert ends[SLID] is not None


def test_a_closure_takes_out_a_slide_at_the_doubted_step_where_plain_edges_cannot() -> None:
    truth = _drive()
    loops = [_closure(truth, 20, 0), _closure(truth, 18, 2)]
    plain = _chain(truth, 0.5, two_way=False)
    plain.edges += loops
    two = _chain(truth, 0.5, two_way=True)
    two.edges += loops
    spread = _error_m(plain.optimise(), truth)
    fixed = _error_m(two.optimise(), truth)
    assert spread > 0.1  # plain edges spread the slide along the loop
    assert fixed < 0.02
    assert two.edges[SLID].taken


def test_without_a_closure_across_it_the_edge_keeps_or_returns_to_the_scans_end() -> None:
    truth = _drive()
    graph = _chain(truth, 0.5, two_way=True)
    poses = graph.optimise()
    assert not graph.edges[SLID].taken
    assert np.allclose(poses, graph.initial, atol=1e-6)
    # an edge that held the odometry's end goes back: nothing says otherwise
    graph.edges[SLID] = graph.edges[SLID].swapped()
    assert graph.edges[SLID].taken
    graph.optimise()
    assert not graph.edges[SLID].taken


def test_an_unsure_closure_leans_to_the_odometrys_end_and_a_sure_one_takes_it() -> None:
    truth = _drive()
    unsure = _chain(truth, 0.5, two_way=True)
    unsure.edges.append(_closure(truth, 20, 0, sigma_m=1.0))
    unsure.optimise()
    assert not unsure.edges[SLID].taken
    sure = _chain(truth, 0.5, two_way=True)
    sure.edges.append(_closure(truth, 20, 0, sigma_m=0.05))
    sure.optimise()
    assert sure.edges[SLID].taken


def test_a_false_constraint_cannot_stretch_a_step_past_both_its_ends() -> None:
    truth = _drive()
    graph = _chain(truth, 0.5, two_way=True)
    # a stiff constraint that puts the loop's end 3 m further on than it is
    x, y, th = _rel(truth, 0, 20)
    graph.edges.append(Edge(0, 20, x + 3.0, y, th, 0.05, math.radians(1.0)))
    # the same step as one Gaussian loose between both ends takes much of the stretch
    edge = graph.edges[SLID]
    loose = PoseGraph(graph.initial, list(graph.edges))
    loose.edges[SLID] = dataclasses.replace(
        edge, dx_m=edge.dx_m - 0.25, other=None, weak_sigma_m=0.25
    )
    assert _rel(loose.optimise(), SLID, SLID + 1)[0] > edge.dx_m + 0.5
    step = _rel(graph.optimise(), SLID, SLID + 1)[0]
    # the two-way edge is as stiff at its end as any other edge: a share of the stretch
    assert abs(step - edge.dx_m) < 0.05


def test_a_solve_that_does_not_choose_keeps_the_ends_held() -> None:
    truth = _drive()
    graph = _chain(truth, 0.5, two_way=True)
    graph.edges.append(_closure(truth, 20, 0))
    held = list(graph.edges)
    graph.optimise(choose=False)
    assert graph.edges == held
    # the same as the graph with a plain edge at the scan's end
    plain = PoseGraph(graph.initial, [dataclasses.replace(e, other=None) for e in held])
    assert np.allclose(graph.optimise(choose=False), plain.optimise(), atol=1e-6)
