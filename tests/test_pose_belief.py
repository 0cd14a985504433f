"""The pose graph's belief (gridmap_cli/poses/uncertainty/pose_belief.py): marginals in the map
frame, the shape covariance with the rigid motion taken out, and joint draws that keep both."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from gridmap_cli.mapping.models.fading import ErrorAwareParams
from gridmap_cli.mapping.pipeline import BuildOptions, _mean_map, build_map, plan_build
from gridmap_cli.poses.correction.pose_graph import Edge, PoseGraph
from gridmap_cli.poses.uncertainty.pose_belief import (
    PoseBelief,
    align_draws,
    calibrated_graph,
    rigid_fit,
    slam_belief,
    to_map_frame,
)
from gridmap_cli.readers import read_log
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import load_robot
from tests.test_pose_graph import _closure, _drifting_graph, _square


def _belief(graph: PoseGraph, samples: int = 0, seed: int = 0) -> PoseBelief:
    """slam_belief of a bare graph: a stand-in for the SlamResult it reads."""
    poses = graph.optimise()
    n = len(poses)
    result = SimpleNamespace(
        graph=graph,
        poses=poses,
        covariance=None,
        keyframes=np.arange(n),
        scan_matched=SimpleNamespace(track=SimpleNamespace(stamp_ns=np.arange(n) * 10**9)),
    )
    return slam_belief(result, samples, seed)  # type: ignore[arg-type]


def _closed_square() -> PoseGraph:
    truth = _square()
    graph = _drifting_graph(truth)
    end = len(truth) - 1
    graph.edges += [_closure(end, 0, truth), _closure(end - 2, 2, truth)]
    return graph


def test_marginals_are_positive_definite_in_the_map_frame() -> None:
    belief = _belief(_closed_square())
    n = len(belief.poses)
    assert belief.cov.shape == belief.shape_cov.shape == (n, 3, 3)
    for cov in (belief.cov[1:], belief.shape_cov):
        assert np.allclose(cov, np.transpose(cov, (0, 2, 1)))
        assert np.linalg.eigvalsh(cov).min() > 0.0


def test_the_map_frame_turns_the_position_block_with_the_heading() -> None:
    own = np.diag([4.0, 1.0, 0.01])[None]  # long along the robot's x
    turned = to_map_frame(own, np.array([math.pi / 2]))[0]
    assert turned[1, 1] == 4.0 and turned[0, 0] < 1.0 + 1e-12  # long along the map's y now
    assert turned[2, 2] == 0.01


def test_a_closed_loop_shrinks_the_covariance_at_its_end() -> None:
    truth = _square()
    open_loop = _belief(_drifting_graph(truth))
    closed = _belief(_closed_square())
    end = len(truth) - 1
    trace = lambda c: float(c[0, 0] + c[1, 1])  # noqa: E731
    # before the loop closes the end is the most uncertain pose; after, it is near the start's
    assert trace(open_loop.cov[end]) == max(trace(c) for c in open_loop.cov)
    assert trace(closed.cov[end]) < 0.2 * trace(open_loop.cov[end])
    assert trace(closed.cov[end]) < trace(closed.cov[end // 2])  # the far side stays looser


def test_the_shape_covariance_takes_out_only_the_rigid_motion() -> None:
    belief = _belief(_closed_square(), samples=400, seed=1)
    # the fit is a least-squares projection of the positions: their summed variance falls
    # (the first pose, pinned by the graph, is no longer exact: it moves with the rest)
    position = lambda c: float((c[:, 0, 0] + c[:, 1, 1]).sum())  # noqa: E731
    assert position(belief.shape_cov) < position(belief.cov)
    assert belief.shape_cov[0, 0, 0] > belief.cov[0, 0, 0]
    # the draws, laid on the optimum by their best rigid fit, spread as the shape covariance says
    error = belief.draws - belief.poses[None]
    error[..., 2] = np.angle(np.exp(1j * error[..., 2]))
    empirical = np.einsum("ski,skj->kij", error, error) / len(error)
    predicted = belief.shape_cov[:, 0, 0] + belief.shape_cov[:, 1, 1]
    ratio = (empirical[:, 0, 0] + empirical[:, 1, 1]) / predicted
    assert 0.8 < float(np.median(ratio)) < 1.25
    # and a laid draw has no rigid motion left to fit
    b, _ = rigid_fit(belief.poses)
    assert np.abs(np.einsum("kij,skj->si", b, error)[:, :2]).max() < 1e-9


def test_joint_draws_spread_as_the_marginals_and_move_neighbours_together() -> None:
    graph = _closed_square()
    poses = graph.optimise()
    draws = graph.sample(poses, 400, seed=2)
    own = graph.marginals(poses)
    error = draws - poses[None]
    cov = to_map_frame(own, poses[:, 2])
    k = 20  # the far side of the loop
    assert 0.8 < error[:, k, 0].var() / cov[k, 0, 0] < 1.25
    # neighbours along the path are strongly correlated (independent draws would give 0)
    assert np.corrcoef(error[:, k, 0], error[:, k + 1, 0])[0, 1] > 0.8
    assert np.array_equal(draws, graph.sample(poses, 400, seed=2))  # the same seed, the same


def test_tracks_follow_the_draws_between_keyframes() -> None:
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    draws = np.array([[[0.0, 0.1, 0.0], [1.0, 0.3, 0.0]]])
    belief = PoseBelief(np.array([0, 10], dtype=np.int64), poses, np.zeros((2, 3, 3)),
                        np.zeros((2, 3, 3)), draws)  # fmt: skip
    track = PoseTrack.from_rows(np.array([0, 5, 10], dtype=np.int64),
                                [(0.0, 0.0, 0.0), (0.5, 0.0, 0.0), (1.0, 0.0, 0.0)])  # fmt: skip
    (drawn,) = belief.tracks(track, 1)
    assert np.allclose(drawn.y_m, [0.1, 0.2, 0.3]) and np.allclose(drawn.x_m, [0.0, 0.5, 1.0])


def test_aligning_removes_a_planted_rigid_motion() -> None:
    poses = _square()
    c, s = math.cos(0.2), math.sin(0.2)
    moved = poses.copy()
    moved[:, 0] = c * poses[:, 0] - s * poses[:, 1] + 3.0
    moved[:, 1] = s * poses[:, 0] + c * poses[:, 1] - 1.0
    moved[:, 2] = poses[:, 2] + 0.2
    laid = align_draws(moved[None], poses)[0]
    assert np.allclose(laid[:, :2], poses[:, :2], atol=1e-9)


SAMPLE = Path(__file__).resolve().parents[1] / "samples" / "corridor_loop.csv"
ROBOT = load_robot("p3at")


def _still_belief(log: RangeLog, spread_m: float) -> PoseBelief:
    """A belief about ``log``'s odometry: every 50th pose a keyframe, a position spread of
    ``spread_m`` (none: every draw is the track itself)."""
    keys = np.arange(0, len(log.poses), 50)
    poses = np.column_stack([log.poses.x_m, log.poses.y_m, log.poses.theta_rad])[keys]
    cov = np.zeros((len(keys), 3, 3))
    cov[:, 0, 0] = cov[:, 1, 1] = spread_m**2
    cov[:, 2, 2] = (spread_m / 10) ** 2
    rng = np.random.default_rng(0)
    draws = poses[None] + rng.normal(0.0, 1.0, (4, *poses.shape)) * [spread_m, spread_m,
                                                                     spread_m / 10]  # fmt: skip
    return PoseBelief(log.poses.stamp_ns[keys], poses, cov, cov, draws)


@pytest.mark.parametrize("samples", [4, 0])
def test_a_belief_without_spread_maps_as_the_standard_model(samples: int) -> None:
    log = read_log(SAMPLE)
    standard = build_map(log, ROBOT, BuildOptions()).map.prob
    options = BuildOptions(mode="error-aware", error_samples=samples)
    still = build_map(log, ROBOT, dataclasses.replace(options, pose_belief=_still_belief(log, 0.0)))
    assert np.array_equal(still.map.prob, standard, equal_nan=True)
    loose = build_map(log, ROBOT, dataclasses.replace(options, pose_belief=_still_belief(log, 0.3)))
    assert not np.array_equal(loose.map.prob, standard, equal_nan=True)


def test_readings_past_the_heading_limit_are_left_out_one_by_one() -> None:
    log = read_log(SAMPLE)
    belief = _still_belief(log, 0.0)
    heading = np.zeros(len(belief.stamp_ns))
    heading[len(heading) // 3 : 2 * len(heading) // 3] = math.radians(20.0) ** 2  # lost, found
    cov = belief.shape_cov.copy()
    cov[:, 2, 2] = heading
    belief = dataclasses.replace(belief, shape_cov=cov)
    params = ErrorAwareParams(max_heading_spread_rad=math.radians(5.0))
    options = BuildOptions(mode="error-aware", error_samples=1, pose_belief=belief,
                           error_aware=params)  # fmt: skip
    limited = build_map(log, ROBOT, options)
    whole = build_map(log, ROBOT, dataclasses.replace(options, error_aware=ErrorAwareParams()))
    # a third of the run is left out, and the readings after it are mapped again
    assert 0.5 * whole.cell_updates < limited.cell_updates < 0.8 * whole.cell_updates


def _twice_round(true_scale: float, seed: int = 0) -> PoseGraph:
    """Two laps of the square, every edge measured with noise ``true_scale`` times the standard
    deviations it is modelled with; each node of the second lap closed on the first lap's."""
    rng = np.random.default_rng(seed)
    lap = _square()
    truth = np.vstack([lap, lap[1:]])
    sxy, sth = 0.05, math.radians(1.0)

    def measured(i: int, j: int, closure: bool) -> Edge:
        a, b = truth[i], truth[j]
        c, s = math.cos(a[2]), math.sin(a[2])
        dx = c * (b[0] - a[0]) + s * (b[1] - a[1]) + true_scale * sxy * rng.standard_normal()
        dy = -s * (b[0] - a[0]) + c * (b[1] - a[1]) + true_scale * sxy * rng.standard_normal()
        dth = math.remainder(b[2] - a[2], 2 * math.pi) + true_scale * sth * rng.standard_normal()
        return Edge(i, j, dx, dy, dth, sxy, sth, closure=closure)

    n = len(lap)
    edges = [measured(k, k + 1, False) for k in range(len(truth) - 1)]
    edges += [measured(k, k + n - 1, True) for k in range(1, n - 1)]
    return PoseGraph(truth.copy(), edges)


@pytest.mark.parametrize("true_scale", [0.3, 1.0])
def test_the_variance_factors_recover_the_true_noise_scale(true_scale: float) -> None:
    graph = _twice_round(true_scale)
    poses = graph.optimise()
    calibrated, (xy, theta) = calibrated_graph(graph, poses)
    # 40 closures, over 100 checks per component: the estimate is within about 20 %
    assert 0.75 * true_scale < xy < 1.3 * true_scale
    assert 0.75 * true_scale < theta < 1.3 * true_scale
    assert calibrated.edges[0].sigma_xy_m == pytest.approx(graph.edges[0].sigma_xy_m * xy)
    assert graph.edges[0].sigma_xy_m == 0.05  # the graph itself is left as it was


def test_an_edge_loose_along_a_corridor_is_checked_and_scaled_as_the_optimiser_weighs_it() -> None:
    """The variance budget whitens each edge by its own covariance, looser along a corridor
    (:meth:`Edge.covariance`), and the calibration scales that looseness with the rest."""
    graph = _twice_round(1.0)
    poses = graph.optimise()
    loose = dataclasses.replace(
        graph,
        edges=[dataclasses.replace(e, weak_sigma_m=0.0 if e.closure else 0.5,
                                   weak_axis=(1.0, 0.0)) for e in graph.edges],
    )  # fmt: skip
    tight, wide = graph.residual_budget(poses), loose.residual_budget(poses)
    # along the corridor the chain's residuals count for less (the hand-set sigma alone: the
    # same budget as the tight graph)
    assert wide[0, 0] < 0.9 * tight[0, 0]
    assert wide[1] == pytest.approx(tight[1], rel=0.05)  # rotation: the same noise
    calibrated, (xy, _) = calibrated_graph(loose, poses)
    chain = calibrated.edges[0]
    assert chain.weak_sigma_m == pytest.approx(0.5 * xy)
    assert chain.sigma_xy_m == pytest.approx(graph.edges[0].sigma_xy_m * xy)


def test_a_graph_without_a_loop_keeps_its_hand_set_noise() -> None:
    graph = _drifting_graph(_square())
    calibrated, scale = calibrated_graph(graph, graph.optimise())
    assert graph.residual_budget(graph.optimise())[:, 1].max() < 1e-6  # nothing checks it
    assert scale == (1.0, 1.0) and calibrated.edges == graph.edges


def test_the_belief_carries_the_calibration_and_narrows_with_it() -> None:
    graph = _twice_round(0.3)
    poses = graph.optimise()
    n = len(poses)
    result = SimpleNamespace(graph=graph, poses=poses, covariance=None, keyframes=np.arange(n),
                             scan_matched=SimpleNamespace(track=SimpleNamespace(
                                 stamp_ns=np.arange(n) * 10**9)))  # fmt: skip
    hand = slam_belief(result, calibrate=False)  # type: ignore[arg-type]
    fitted = slam_belief(result)  # type: ignore[arg-type]
    assert hand.scale == (1.0, 1.0) and fitted.scale[0] < 0.5
    ratio = fitted.shape_cov[:, 0, 0] / hand.shape_cov[:, 0, 0]
    assert 0.5 * fitted.scale[0] ** 2 < float(np.median(ratio)) < 2.0 * fitted.scale[0] ** 2


def test_the_sampled_map_clamps_once_so_walls_a_few_draws_miss_stay_walls() -> None:
    log = read_log(SAMPLE)
    standard = build_map(log, ROBOT, BuildOptions()).map.prob
    belief = _still_belief(log, 0.05)
    options = BuildOptions(mode="error-aware", error_samples=4, pose_belief=belief)
    once = build_map(log, ROBOT, options).map.prob
    # the per-sample clamp, as the odometry's banded map takes it
    tracks = belief.tracks(log.poses, 4)
    plan = plan_build(log, ROBOT, BuildOptions())
    each = _mean_map(log, plan, BuildOptions(), tracks, None).map.prob
    occupied = lambda p: int(np.nansum(p >= 0.65))  # noqa: E731
    assert occupied(each) < 0.6 * occupied(once)  # 5 cm of spread halved the clamped walls
    assert occupied(once) > 0.8 * occupied(standard)
    assert np.nanmax(once) <= 0.7 and np.nanmin(once) >= 0.01  # the mean is clamped as a map is
    assert np.array_equal(np.isnan(once), np.isnan(each))  # unknown stays unknown
