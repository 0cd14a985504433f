"""The loop-closure search where the estimate has drifted: several keyframes are offered, and a
submap seen from the other direction still finds GICP a start."""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
import pytest

from gridmap_cli.poses.correction.correlative import LikelihoodGrid, search
from gridmap_cli.poses.correction.loop_closure import ClosureParams, anchors, candidates


def _line(x0: float, y0: float, x1: float, y1: float, step_m: float = 0.5) -> np.ndarray:
    n = max(2, round(math.hypot(x1 - x0, y1 - y0) / step_m) + 1)
    th = math.atan2(y1 - y0, x1 - x0)
    return np.column_stack([np.linspace(x0, x1, n), np.linspace(y0, y1, n), np.full(n, th)])


def _a_pass_then_back() -> tuple[np.ndarray, int]:
    """A 20 m pass, a long excursion, and a last keyframe 2 m beside the pass's middle."""
    legs = [
        _line(0, 0, 20, 0),  # the earlier pass
        _line(20, 0, 20, 60),  # far away and back: the gap is long, the window wide
        _line(20, 60, 10, 60),
        _line(10, 60, 10, 2),
    ]
    return np.vstack(legs), sum(len(leg) for leg in legs) - 1


def test_several_keyframes_of_a_drifted_return_are_offered() -> None:
    poses, last = _a_pass_then_back()
    path = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poses[:, :2], axis=0).T))])
    pairs = [j for i, j in candidates(poses, np.array([last]), ClosureParams())]
    # the nearest first, then the next nearest more than 2 m of path from those taken
    assert len(pairs) == 3 and pairs[0] == 20
    assert all(abs(path[a] - path[b]) > 2.0 for a, b in itertools.combinations(pairs, 2))
    assert all(j <= 40 for j in pairs)  # all on the earlier pass
    only = [
        j for i, j in candidates(poses, np.array([last]), ClosureParams(max_candidates_per_node=1))
    ]
    assert only == [20]


def _room(step_m: float = 0.05) -> np.ndarray:
    corners = [(0, 0), (8, 0), (8, 3), (4, 3), (4, 7), (0, 7), (0, 0)]
    walls = []
    for (x0, y0), (x1, y1) in itertools.pairwise(corners):
        n = max(2, int(math.hypot(x1 - x0, y1 - y0) / step_m))
        walls.append(np.column_stack([np.linspace(x0, x1, n), np.linspace(y0, y1, n)]))
    return np.vstack(walls)


def test_closures_are_offered_between_anchors_only() -> None:
    every = anchors(np.arange(10.0) * 0.5, 1.0)
    assert every.tolist() == [0, 2, 4, 6, 8]
    # a turn in place (keyframes with no path between them) gives one anchor at most
    assert anchors(np.array([0.0, 1.0, 1.0, 1.0, 1.0, 2.5]), 1.0).tolist() == [0, 1, 5]
    poses, last = _a_pass_then_back()
    path = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poses[:, :2], axis=0).T))])
    spots = anchors(path, 1.0)
    assert len(spots) < len(poses)
    pairs = candidates(poses, np.array([last]), ClosureParams(), targets=spots)
    assert pairs and all(j in spots.tolist() for _, j in pairs)
    assert len(pairs) == 3  # as many as without anchors, all on the earlier pass
    assert all(j <= 40 for _, j in pairs)


def test_a_submap_half_seen_by_the_target_finds_its_start() -> None:
    # the source saw the room's lower half and walls beyond it the target never saw (the other
    # direction of travel): half its points overlap the target
    room = _room()
    target = room[room[:, 1] <= 3.5]
    rng = np.random.default_rng(5)
    unseen = np.column_stack(
        [rng.uniform(9.0, 14.0, len(target)), rng.uniform(0.0, 3.0, len(target))]
    )
    truth = (1.6, -1.1, math.radians(6.0))
    seen = np.vstack([target, unseen])
    c, s = math.cos(truth[2]), math.sin(truth[2])
    d = seen - np.array(truth[:2])
    source = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])[::4]
    p = ClosureParams()
    grid = LikelihoodGrid(target, p.coarse_resolution_m, p.coarse_sigma_m, 5, 4.0)
    found = search(grid, source, (0.0, 0.0, 0.0), 4.0, p.coarse_window_rad, p.coarse_step_rad,
                   p.coarse_min_score)  # fmt: skip
    assert found is not None
    assert math.hypot(found.x_m - truth[0], found.y_m - truth[1]) < 0.15
    assert abs(found.theta_rad - truth[2]) < math.radians(1.5)
    # the half overlap scores under one half: a gate at 0.5 would have refused the true pose
    assert found.score < 0.5


def test_the_inlier_share_counts_every_registered_point() -> None:
    # the share is over the source submap's points (its voxels, each once), each within
    # inlier_m of the target's nearest point or not, as a plain tree query finds them
    from scipy.spatial import cKDTree

    from gridmap_cli.poses.correction.loop_closure import Submaps, _align

    room = _room(0.02)
    n = 12
    local = np.column_stack([np.linspace(1.0, 3.0, n), np.full(n, 1.5), np.zeros(n)])
    rng = np.random.default_rng(3)
    scans = []
    for x, y, _ in local:  # each scan: the room's walls in the robot's frame, a little noisy
        seen = room[rng.random(len(room)) < 0.5] - (x, y)
        scans.append(seen + rng.normal(0.0, 0.01, seen.shape))
    p = ClosureParams()
    submaps = Submaps(scans, local, np.arange(n), p)
    target, source = submaps.get(0), submaps.get(n - 1, wide=False)
    # the registered points are the submap's points, each once, each with its sheet's
    # covariances (the kernel's three layers, or small_gicp's cloud where it is not built)
    assert len(np.unique(source.points, axis=0)) == len(source.points)
    if source.covs is not None:
        assert source.covs.shape == (len(source.points), 3, 6)
    else:
        assert source.cloud is not None and source.cloud.size() >= len(source.points)
    for start in [(2.0, 0.0, 0.0), (2.3, 0.4, 0.2), (1.0, -1.0, 0.6)]:
        result = _align(target, source, start, p)
        assert result is not None
        share, (x, y, th), _ = result
        c, s = math.cos(th), math.sin(th)
        moved = source.points @ np.array([[c, s], [-s, c]]) + (x, y)
        dist, _ = cKDTree(target.points).query(moved, distance_upper_bound=p.inlier_m)
        assert share == float(np.mean(np.isfinite(dist)))


def test_a_target_at_either_end_of_the_log_keeps_its_length() -> None:
    # a straight run, each scan two wall points abeam of the robot: a submap's points span the
    # travel its scans cover; at the log's first and last scans the target (not the source)
    # takes the whole of its length on the one side it has
    from gridmap_cli.poses.correction.loop_closure import Submaps

    n = 121
    local = np.column_stack([np.linspace(0.0, 30.0, n), np.zeros(n), np.zeros(n)])
    scans = [np.array([[0.0, 1.0], [0.0, -1.0]]) for _ in range(n)]
    p = ClosureParams()
    submaps = Submaps(scans, local, np.arange(n), p)

    def extent(node: int, wide: bool) -> tuple[float, float]:
        x = submaps.get(node, wide).points[:, 0] + local[node, 0]
        return float(x.min()), float(x.max())

    assert extent(0, True) == pytest.approx((0.0, 2 * p.submap_m), abs=0.3)
    assert extent(n - 1, True) == pytest.approx((30.0 - 2 * p.submap_m, 30.0), abs=0.3)
    assert extent(60, True) == pytest.approx((15.0 - p.submap_m, 15.0 + p.submap_m), abs=0.3)
    # the source is what the robot saw about the node, at the ends too
    assert extent(0, False) == pytest.approx((0.0, p.source_m), abs=0.3)
    assert extent(n - 1, False) == pytest.approx((30.0 - p.source_m, 30.0), abs=0.3)


def test_built_submaps_are_kept_within_their_byte_budget(monkeypatch: pytest.MonkeyPatch) -> None:
    # the closure rounds come back to the same submaps: those kept are the ones built (the same
    # object again), the least recently used go first once the budget is spent, and one evicted
    # is built again with the same points
    from gridmap_cli.poses.correction import loop_closure
    from gridmap_cli.poses.correction.loop_closure import Submaps, _sheet_bytes

    n = 61
    local = np.column_stack([np.linspace(0.0, 30.0, n), np.zeros(n), np.zeros(n)])
    rng = np.random.default_rng(1)
    scans = [rng.uniform(-3.0, 3.0, (40, 2)) for _ in range(n)]
    whole = Submaps(scans, local, np.arange(n), ClosureParams())
    sizes = [_sheet_bytes(whole.get(node)) for node in (0, 30, 60)]
    assert all(size > 0 for size in sizes)
    # room for node 0's submap and either other one, not for all three
    monkeypatch.setattr(loop_closure, "CACHED_SUBMAP_BYTES", sizes[0] + max(sizes[1:]))
    submaps = Submaps(scans, local, np.arange(n), ClosureParams())
    first, second = submaps.get(0), submaps.get(30)
    assert submaps.get(0) is first and submaps.get(30) is second  # both fit
    submaps.get(0)  # 30 is now the least recently used
    third = submaps.get(60)
    assert submaps.get(0) is first
    again = submaps.get(30)
    assert again is not second  # evicted, built afresh
    np.testing.assert_array_equal(again.points, second.points)
    assert submaps.get(60) is not third  # and 60 gave way to it in turn


def test_shorter_loops_are_tried_first_by_doubling_length() -> None:
    """Pairs grouped by the path between them (8-16 m, 16-32 m, 32-64 m, ... from the shortest
    loop of 8 m), keyed by the doubling, each group in the order it was offered."""
    from gridmap_cli.poses.correction.slam import by_gap

    path = np.arange(0.0, 200.0, 1.0)  # node k at k metres along the path
    pairs = [(100, 0), (30, 20), (50, 10), (60, 50), (99, 90), (41, 10), (150, 130)]
    tiers = by_gap(pairs, path, 8.0)
    assert tiers == {
        0: [(30, 20), (60, 50), (99, 90)],
        1: [(41, 10), (150, 130)],
        2: [(50, 10)],
        3: [(100, 0)],
    }
    assert by_gap([], path, 8.0) == {}


def test_a_search_has_drifted_when_its_closures_turn_the_track_by_half_its_window() -> None:
    """The closures' median heading correction from the scan-matched track against half the
    coarse search's heading window; the track's own turn between the two nodes is no
    correction."""
    from gridmap_cli.poses.correction.loop_closure import Closure
    from gridmap_cli.poses.correction.repair import drifted
    from gridmap_cli.records import PoseTrack

    k = np.arange(40)
    heading = 0.05 * k  # the track turns as it goes: a closure's own turn is taken off
    track = PoseTrack(
        stamp_ns=k.astype(np.int64), x_m=np.cos(heading), y_m=np.sin(heading), theta_rad=heading
    )
    nodes = np.arange(0, 40, 2)
    params = ClosureParams(coarse_window_rad=math.radians(15.0))

    def closures(corrections_deg: list[float]) -> list[Closure]:
        # node j's pose in node i's frame: the track's relative turn plus the correction
        out = []
        for n, deg in enumerate(corrections_deg):
            i, j = 15 + n, 2
            turn = heading[nodes[j]] - heading[nodes[i]]
            out.append(Closure(i, j, 0.0, 0.0, turn + math.radians(deg), 0.6))
        return out

    assert drifted(track, nodes, closures([9.0, -8.0, 0.5]), params)  # median 8 > 7.5
    assert not drifted(track, nodes, closures([9.0, 7.0, -0.5]), params)  # median 7
    assert not drifted(track, nodes, closures([0.0, 0.0, 0.0]), params)
    assert not drifted(track, nodes, [], params)
    wide = ClosureParams(coarse_window_rad=math.radians(30.0))
    assert not drifted(track, nodes, closures([9.0, -8.0, 0.5]), wide)


def test_a_longer_loops_pairs_are_chosen_from_the_track_its_shorter_loops_corrected(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Within a round, each length of loop is offered the pairs that lie near each other in the
    estimate solved after the shorter loops' closures, not in the round's first estimate: in a
    drifted estimate the keyframes nearest a stretch are its neighbours'."""
    from gridmap_cli.poses.correction import slam
    from gridmap_cli.poses.correction.scan_match import log_scans, match_scans
    from tests.test_scan_match import laser_robot, room_world
    from tests.test_scan_match import run as simulate_run

    # two laps of the room: loops of more than one length
    lap = [[2, 1.5], [10, 1.5], [10, 6.5], [2, 6.5], [2, 1.5]]
    log = simulate_run(room_world(), lap + lap[1:], drift=1.0)
    scans = log_scans(log, laser_robot(), slam.SLAM_MATCH)
    match = match_scans(scans, log.poses, slam.SLAM_MATCH)
    offered: list[tuple[np.ndarray, set[tuple[int, int]]]] = []
    verified: list[tuple[int, int, np.ndarray]] = []
    real_candidates, real_verify, real_relative = slam.candidates, slam.verify, slam.relative
    now: list[np.ndarray] = []

    def spy_candidates(poses: np.ndarray, *args: Any, **kwargs: Any) -> list[tuple[int, int]]:
        pairs = real_candidates(poses, *args, **kwargs)
        offered.append((poses.copy(), set(pairs)))
        return pairs

    def spy_relative(poses: np.ndarray, i: int, j: int) -> tuple[float, float, float]:
        now[:] = [poses]
        return real_relative(poses, i, j)

    def spy_verify(i: int, j: int, *args: Any, **kwargs: Any) -> Any:
        verified.append((i, j, now[0].copy()))
        return real_verify(i, j, *args, **kwargs)

    monkeypatch.setattr(slam, "candidates", spy_candidates)
    monkeypatch.setattr(slam, "relative", spy_relative)
    monkeypatch.setattr(slam, "verify", spy_verify)
    slam.optimise_with_closures(scans, match, slam.SlamParams())
    # the estimate each pair was guessed from is the one its pairs were chosen from
    assert verified
    for i, j, estimate in verified:
        chosen = [pairs for poses, pairs in offered if np.array_equal(poses, estimate)]
        assert chosen and (i, j) in chosen[-1]
    # and the pairs were chosen again within a round, after a solve
    assert len({poses.tobytes() for poses, _ in offered}) > slam.SlamParams().rounds
