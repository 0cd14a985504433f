"""A track that fails its free-space check tries the loops only closures under the gate close,
and takes out the loops of closures that do not hold on their target's view."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from gridmap_cli.poses.correction import repair, slam
from gridmap_cli.poses.correction.loop_closure import Closure, ClosureParams, Submaps
from gridmap_cli.poses.correction.pose_graph import Edge, PoseGraph
from gridmap_cli.poses.correction.sheet_gicp import sheet_of


def test_a_submaps_scans_are_what_its_points_are_made_of() -> None:
    rng = np.random.default_rng(5)
    n = 60
    local = np.column_stack(
        [np.linspace(0.0, 12.0, n), np.linspace(0.0, 3.0, n), np.linspace(0.0, 1.0, n)]
    )
    scans = [rng.uniform(-4.0, 4.0, (40, 2)) for _ in range(n)]
    submaps = Submaps(scans, local, np.arange(0, n, 5), ClosureParams())
    for node, wide in [(0, True), (6, True), (6, False), (11, True)]:
        xyz, points = submaps.scans(node, wide)
        assert len(xyz) == len(points) > 1
        placed = []
        for (x, y, th), p in zip(xyz, points, strict=True):
            c, s = math.cos(th), math.sin(th)
            placed.append(
                np.column_stack([x + c * p[:, 0] - s * p[:, 1], y + s * p[:, 0] + c * p[:, 1]])
            )
        voxel = submaps.params.voxel_m if wide else submaps.params.source_voxel_m
        ours = sheet_of(np.vstack(placed), voxel).points
        theirs = submaps.get(node, wide).points
        assert len(ours) == len(theirs)
        assert np.allclose(np.sort(ours, axis=0), np.sort(theirs, axis=0), atol=1e-9)


@dataclasses.dataclass
class _Check:
    fails: bool
    share: float
    revisits: int = 100


def _loop() -> tuple[PoseGraph, np.ndarray, dict[tuple[int, int], Closure], list[Closure]]:
    """A square loop of 40 nodes whose odometry drifted 2 m at its end; no closure accepted,
    and two groups of closures under the gate: one at the loop's end, one elsewhere."""
    n = 40
    side = n // 4
    xy = []
    for k in range(n):
        leg, t = divmod(k, side)
        corner = [(0, 0), (10, 0), (10, 10), (0, 10)][leg]
        step = [(1, 0), (0, 1), (-1, 0), (0, -1)][leg]
        xy.append((corner[0] + step[0] * t, corner[1] + step[1] * t))
    truth = np.array([(x, y, 0.0) for x, y in xy])
    drifted = truth + np.column_stack([np.linspace(0, 2.0, n), np.zeros(n), np.zeros(n)])
    edges = [
        Edge(k, k + 1, *(truth[k + 1, :2] - truth[k, :2]), 0.0, 0.1, 0.01) for k in range(n - 1)
    ]
    graph = PoseGraph(drifted.copy(), edges)

    def closure(i: int, j: int) -> Closure:
        d = truth[j, :2] - truth[i, :2]
        return Closure(i, j, float(d[0]), float(d[1]), 0.0, 0.3)

    partial = [closure(39, 0), closure(38, 1), closure(25, 3)]
    return graph, drifted, {}, partial


def _run(
    monkeypatch: pytest.MonkeyPatch, checks: list[_Check]
) -> tuple[np.ndarray, np.ndarray, dict[tuple[int, int], Closure]]:
    graph, estimate, accepted, partial = _loop()
    calls = iter(checks)
    monkeypatch.setattr(repair, "check_poses", lambda track, points: next(calls))
    monkeypatch.setattr(repair, "carried", lambda match, nodes, poses: None)
    monkeypatch.setattr(repair, "holds_where_seen", lambda submaps, k: True)
    params = dataclasses.replace(slam.SlamParams(), reject_m=10.0, reject_rad=1.0)
    out, _ = repair.partial_loops(
        SimpleNamespace(points=[]),  # type: ignore[arg-type]
        None,  # type: ignore[arg-type]
        np.arange(40),
        graph,
        estimate,
        accepted,
        partial,
        None,  # type: ignore[arg-type]
        params,
    )
    return estimate, out, accepted


def test_a_track_that_passes_is_left_as_it_is(monkeypatch: pytest.MonkeyPatch) -> None:
    before, after, accepted = _run(monkeypatch, [_Check(False, 0.0)])
    assert after is before and accepted == {}


def test_a_failing_track_keeps_the_group_that_lowers_its_contradictions(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # failing; with the loop's end group fewer places contradict and the track passes
    before, after, accepted = _run(monkeypatch, [_Check(True, 0.2), _Check(False, 0.01)])
    assert set(accepted) == {(39, 0), (38, 1)}
    # the loop's end came home: node 39 is truly 1 m from node 0, drifted 2 m further
    assert np.hypot(*(before[39, :2] - before[0, :2])) > 2.0
    assert np.hypot(*(after[39, :2] - after[0, :2])) == pytest.approx(1.0, abs=0.3)


def test_a_group_that_does_not_lower_the_contradictions_is_not_kept(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    before, after, accepted = _run(
        monkeypatch, [_Check(True, 0.2), _Check(True, 0.2), _Check(True, 0.25)]
    )
    assert accepted == {}
    assert np.array_equal(after, before)


def test_closures_are_grouped_by_the_loop_they_close() -> None:
    from gridmap_cli.poses.correction.repair import by_loop

    path = np.arange(100, dtype=float)  # a metre of path per node

    def k(i: int, j: int) -> Closure:
        return Closure(i, j, 0.0, 0.0, 0.0, 0.3)

    # two closures of one loop (ends 2 m apart at both ends), one of another, one of a loop an
    # accepted closure already closes
    groups = by_loop([k(90, 10), k(60, 30), k(92, 12), k(50, 5)], [(51, 4)], path, 5.0)
    assert sorted((g.i, g.j) for g in groups[0]) == [(60, 30)]
    assert sorted((g.i, g.j) for g in groups[1]) == [(90, 10), (92, 12)]
    assert len(groups) == 2


CARMEN = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "carmen"


@pytest.mark.skipif(not CARMEN.is_dir(), reason="../shared/data/carmen is not present")
def test_the_graphs_own_check_is_the_tracks() -> None:
    # where the graph took the free-space check of its track (a real log has candidates under
    # the gate), it is the check the build would take of the same track and scans, which the
    # build reuses
    from gridmap_cli.poses.correction.free_space import check_poses
    from gridmap_cli.poses.correction.slam import slam_log
    from gridmap_cli.readers import read_logs
    from gridmap_cli.readers.options import ReadOptions
    from gridmap_cli.robot import robot_from_log

    path = CARMEN / "seattle-corrected.log.gz"
    log = read_logs((path,), None, ReadOptions())
    result = slam_log(log, robot_from_log(path, log.metadata))
    assert result.scans is not None and result.free_space is not None
    again = check_poses(result.track, result.scans.points)
    assert result.free_space.as_dict() == again.as_dict()
    assert np.array_equal(result.free_space.shares, again.shares)


def test_a_kept_closure_under_the_gate_is_counted_kept_not_rejected(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from gridmap_cli.poses.correction.scan_match import log_scans
    from gridmap_cli.poses.correction.slam import SLAM_MATCH, slam_scans
    from tests.test_scan_match import laser_robot, room_world
    from tests.test_scan_match import run as simulate_run

    log = simulate_run(room_world(), [[2, 1.5], [10, 1.5], [10, 6.5]], drift=1.0)
    scans = log_scans(log, laser_robot(), SLAM_MATCH)
    real = slam.optimise_with_closures

    def with_one_kept(*args, **kwargs):  # type: ignore[no-untyped-def]
        nodes, poses, graph, closures, tried, rejected, dropped, check = real(*args, **kwargs)
        under = Closure(int(len(nodes) - 1), 0, 1.0, 0.0, 0.0, 0.2)  # kept by a failing track
        return nodes, poses, graph, [*closures, under], tried, rejected + 1, dropped, check

    monkeypatch.setattr(slam, "optimise_with_closures", with_one_kept)
    result = slam_scans(scans, log.poses)
    baseline = real(scans, result.scan_matched, slam.SlamParams())
    assert result.partial == 1
    assert result.rejected == baseline[5]
    summary = result.summary()
    assert summary["closures_of_partial_overlap"] == 1
    assert summary["closures_accepted"] == len(baseline[3]) + 1


def _doubted(
    monkeypatch: pytest.MonkeyPatch, checks: list[_Check]
) -> tuple[np.ndarray, np.ndarray, dict[tuple[int, int], Closure], list[tuple[int, int]]]:
    """:func:`_loop` with two closures accepted: the loop's end (node 39 a metre behind node 0)
    and a look-alike 2 m along the first side (node 25 onto node 3), doubted by its target's
    view; ``checks`` the free-space checks the repair takes in turn. The estimate before and
    after, the closures kept, and the closures the target's view was asked of."""
    graph, estimate, _, _ = _loop()
    true = Closure(39, 0, 0.0, -1.0, 0.0, 0.6)
    false = Closure(25, 3, -2.0, -7.0, 0.0, 0.5)  # truly (-2, -10): 3 m short
    accepted = {(39, 0): true, (25, 3): false}
    calls = iter(checks)
    asked: list[tuple[int, int]] = []

    def holds(submaps: object, k: Closure) -> bool:
        asked.append((k.i, k.j))
        return k is not false

    monkeypatch.setattr(repair, "check_poses", lambda track, points: next(calls))
    monkeypatch.setattr(repair, "carried", lambda match, nodes, poses: None)
    monkeypatch.setattr(repair, "holds_where_seen", holds)
    params = dataclasses.replace(slam.SlamParams(), reject_m=10.0, reject_rad=1.0)
    repair.with_closures(graph, accepted.values(), params)
    before = graph.optimise(estimate, repair.KERNEL_STAGES)
    after, _ = repair.doubted_loops(
        SimpleNamespace(points=[]),  # type: ignore[arg-type]
        None,  # type: ignore[arg-type]
        np.arange(40),
        graph,
        before,
        accepted,
        None,  # type: ignore[arg-type]
        params,
    )
    assert sorted((e.i, e.j) for e in graph.edges if e.closure) == sorted(accepted)
    return before, after, accepted, asked


def test_a_passing_track_keeps_its_closures_unasked(monkeypatch: pytest.MonkeyPatch) -> None:
    before, after, accepted, asked = _doubted(monkeypatch, [_Check(False, 0.0)])
    assert after is before and set(accepted) == {(39, 0), (25, 3)} and asked == []


def test_a_failing_track_takes_out_the_loop_of_a_doubted_closure_that_contradicts(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    before, after, accepted, asked = _doubted(monkeypatch, [_Check(True, 0.2), _Check(False, 0.01)])
    assert sorted(asked) == [(25, 3), (39, 0)]
    assert set(accepted) == {(39, 0)}
    # the track is the graph's solution without the look-alike: its pull on node 25 is gone
    assert not np.allclose(after, before, atol=1e-3)
    assert np.hypot(*(after[25, :2] - after[3, :2])) > np.hypot(*(before[25, :2] - before[3, :2]))


def test_a_doubted_loop_stays_where_taking_it_out_does_not_help(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # no fewer contradicting; or fewer, but only because half the revisits are gone
    for without in (_Check(True, 0.25), _Check(False, 0.01, revisits=40)):
        before, after, accepted, _ = _doubted(monkeypatch, [_Check(True, 0.2), without])
        assert set(accepted) == {(39, 0), (25, 3)}
        assert np.array_equal(after, before)
        monkeypatch.undo()
