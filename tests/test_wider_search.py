"""A track that fails its free-space check or its wide look, or whose closures show it drifted
as far as the search allowed, searches for closures again with its bounds on the drift wider
(:mod:`gridmap_cli.poses.correction.repair`); any other track never does, and a wider search
is kept only where its track does better."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gridmap_cli.cli.build_report import widened_clause
from gridmap_cli.geometry import compose, inverse
from gridmap_cli.poses.correction import slam
from gridmap_cli.poses.correction.loop_closure import ClosureParams
from gridmap_cli.poses.correction.repair import PASSES, WIDER_SEARCH, wider
from gridmap_cli.records import PoseTrack


def test_wider_bounds_grow_by_the_factor_and_the_heading_window_stops_all_round() -> None:
    base = ClosureParams()
    twice = wider(base, 2.0)
    assert twice.drift_per_m == 2 * base.drift_per_m
    assert twice.max_search_m == 2 * base.max_search_m
    assert twice.coarse_window_rad == 2 * base.coarse_window_rad
    # everything else is the search as asked: the gate, the submaps, the coarse grid
    same = dataclasses.replace(
        twice,
        drift_per_m=base.drift_per_m,
        max_search_m=base.max_search_m,
        coarse_window_rad=base.coarse_window_rad,
    )
    assert same == base
    assert wider(base, 100.0).coarse_window_rad == math.pi


@dataclasses.dataclass
class _Check:
    fails: bool
    share: float
    revisits: int = 100
    contradicting: int = 0


@pytest.fixture(scope="module")
def room_scans() -> tuple[Any, Any]:
    from gridmap_cli.poses.correction.scan_match import log_scans, match_scans
    from tests.test_scan_match import laser_robot, room_world
    from tests.test_scan_match import run as simulate_run

    log = simulate_run(room_world(), [[2, 1.5], [10, 1.5], [10, 6.5]], drift=1.0)
    scans = log_scans(log, laser_robot(), slam.SLAM_MATCH)
    return scans, match_scans(scans, log.poses, slam.SLAM_MATCH)


def _close(
    monkeypatch: pytest.MonkeyPatch,
    room_scans: tuple[Any, Any],
    checks: list[_Check],
    stages: list[str] | None = None,
    stands: list[tuple[int, float]] | None = None,
    drifts: list[bool] | None = None,
) -> tuple[slam.SlamResult, list[ClosureParams]]:
    """close_loops with the graph's checks of its tracks given in turn (and how each stands,
    by default as its check alone says; whether the search kept has drifted, by default
    never); the closure search parameters of each pass."""
    scans, match = room_scans
    real = slam.optimise_with_closures
    asked: list[ClosureParams] = []

    def recorded(*args: Any, **kwargs: Any) -> Any:
        asked.append(args[2].closure)
        *found, _ = real(*args, **kwargs)
        return (*found, None)  # the check is the one below

    calls = iter(checks)
    ranks = iter(stands or [(2, c.share) if c.fails else PASSES for c in checks])
    drift = iter(drifts or [False] * (len(checks) + 1))
    monkeypatch.setattr(slam, "optimise_with_closures", recorded)
    monkeypatch.setattr(slam, "check_poses", lambda track, points: next(calls))
    monkeypatch.setattr(slam, "standing", lambda track, points, check: next(ranks))
    monkeypatch.setattr(slam, "drifted", lambda *args: next(drift))
    seen = [] if stages is None else stages
    return slam.close_loops(scans, match, progress=lambda stage, *_: seen.append(stage)), asked


def test_a_passing_track_searches_once(
    monkeypatch: pytest.MonkeyPatch, room_scans: tuple[Any, Any]
) -> None:
    result, asked = _close(monkeypatch, room_scans, [_Check(False, 0.0)])
    assert asked == [ClosureParams()]
    assert result.widened == 1.0
    assert result.summary()["closure_search_widened"] == 1.0
    assert result.summary()["closure_search_widened_for"] is None
    assert widened_clause(result.summary()) == ""  # the summary line says nothing more


def test_a_failing_track_keeps_the_first_wider_search_that_passes(
    monkeypatch: pytest.MonkeyPatch, room_scans: tuple[Any, Any]
) -> None:
    stages: list[str] = []
    result, asked = _close(
        monkeypatch, room_scans, [_Check(True, 0.2), _Check(False, 0.01)], stages
    )
    assert asked == [ClosureParams(), wider(ClosureParams(), WIDER_SEARCH[0])]
    # the search run again shows as a stage of its own
    assert stages[0] == "loop closures" and stages[-1] == "loop closures, 2x wider"
    assert result.widened == WIDER_SEARCH[0]
    assert result.widened_for == "check"
    assert widened_clause(result.summary()) == (
        ", the closure search run again wider (the track as asked failed its free-space check),"
        " kept 2 times as wide"
    )
    assert result.free_space is not None and not result.free_space.fails


def test_a_wider_search_that_does_no_better_is_not_kept(
    monkeypatch: pytest.MonkeyPatch, room_scans: tuple[Any, Any]
) -> None:
    checks = [_Check(True, 0.2), _Check(True, 0.3), _Check(True, 0.1)]
    result, asked = _close(monkeypatch, room_scans, checks)
    # every widening tried while the track fails; the last, with fewer places contradicting,
    # kept over the first
    assert asked == [ClosureParams(), *(wider(ClosureParams(), f) for f in WIDER_SEARCH)]
    assert result.widened == WIDER_SEARCH[-1]
    assert result.free_space is not None and result.free_space.share == 0.1

    checks = [_Check(True, 0.2), _Check(True, 0.3), _Check(True, 0.25)]
    result, _ = _close(monkeypatch, room_scans, checks)
    assert result.widened == 1.0
    assert result.free_space is not None and result.free_space.share == 0.2


def test_a_track_failing_the_wide_look_searches_wider_and_keeps_what_passes_both(
    monkeypatch: pytest.MonkeyPatch, room_scans: tuple[Any, Any]
) -> None:
    # the check passes as asked; the wide look fails (1, its share), then both pass
    checks = [_Check(False, 0.01), _Check(False, 0.01)]
    result, asked = _close(monkeypatch, room_scans, checks, stands=[(1, 0.05), PASSES])
    assert asked == [ClosureParams(), wider(ClosureParams(), WIDER_SEARCH[0])]
    assert result.widened == WIDER_SEARCH[0] and result.widened_for == "wide look"
    # a wider track failing the check ranks below one failing the wide look: not kept
    checks = [_Check(False, 0.01), _Check(True, 0.02), _Check(True, 0.02)]
    stands = [(1, 0.05), (2, 0.02), (2, 0.02)]
    result, asked = _close(monkeypatch, room_scans, checks, stands=stands)
    assert len(asked) == 3 and result.widened == 1.0 and result.widened_for == "wide look"


def test_a_drifted_search_is_widened_and_kept_where_more_revisits_agree(
    monkeypatch: pytest.MonkeyPatch, room_scans: tuple[Any, Any]
) -> None:
    # every track passes both looks; the search as asked has drifted, twice as wide too
    checks = [_Check(False, 0.0, 100), _Check(False, 0.0, 150), _Check(False, 0.0, 140)]
    result, asked = _close(monkeypatch, room_scans, checks, drifts=[True, True])
    assert asked == [ClosureParams(), *(wider(ClosureParams(), f) for f in WIDER_SEARCH)]
    # twice as wide agrees at more revisits (150 of 100) and is kept; four times (140) is not
    assert result.widened == WIDER_SEARCH[0] and result.widened_for == "drift"
    # a wider track that agrees at no more revisits is not kept, the drift or not
    checks = [_Check(False, 0.0, 100), _Check(False, 0.0, 100), _Check(False, 0.0, 90, 5)]
    result, asked = _close(monkeypatch, room_scans, checks, drifts=[True])
    assert len(asked) == 3 and result.widened == 1.0
    assert widened_clause(result.summary()).endswith(
        "(its closures showed a drift as large as the search allowed), kept as asked"
    )
    # a drifted search that is widened stops once the wider one has not drifted
    checks = [_Check(False, 0.0, 100), _Check(False, 0.0, 150)]
    result, asked = _close(monkeypatch, room_scans, checks, drifts=[True, False])
    assert len(asked) == 2 and result.widened == WIDER_SEARCH[0]


def _bent(track: PoseTrack, rad_per_m: float) -> PoseTrack:
    """``track`` with every step turned further by ``rad_per_m`` per metre it moved: a scan
    matcher drifting far more than the closure search's bounds expect."""
    x, y, th = [track.x_m[0]], [track.y_m[0]], [track.theta_rad[0]]
    for k in range(1, len(track.x_m)):
        dx, dy, dth = compose(
            *inverse(track.x_m[k - 1], track.y_m[k - 1], track.theta_rad[k - 1]),
            track.x_m[k], track.y_m[k], track.theta_rad[k],
        )  # fmt: skip
        turn = float(dth) + rad_per_m * math.hypot(float(dx), float(dy))
        nx, ny, nth = compose(x[-1], y[-1], th[-1], float(dx), float(dy), turn)
        x.append(float(nx))
        y.append(float(ny))
        th.append(float(nth))
    return PoseTrack(track.stamp_ns.copy(), np.array(x), np.array(y), np.array(th))


def test_a_track_drifting_past_the_bounds_closes_its_loops_searched_wider(
    tmp_path: Path,
) -> None:
    from gridmap_cli.poses.correction.scan_match import log_scans, match_scans
    from gridmap_cli.poses.sync import interpolate_pose
    from gridmap_cli.poses.track_error import track_error
    from gridmap_cli.readers import read_logs
    from gridmap_cli.readers.options import ReadOptions
    from gridmap_cli.robot import robot_from_log
    from tests.helpers import simulated_laser_log

    path = simulated_laser_log(tmp_path)
    log = read_logs((path,), None, ReadOptions())
    assert log.truth is not None
    scans = log_scans(log, robot_from_log(path, log.metadata), slam.SLAM_MATCH)
    match = match_scans(scans, log.poses, slam.SLAM_MATCH)

    def ape(track: PoseTrack) -> float:
        assert log.truth is not None
        x, y, th, _ = interpolate_pose(log.truth, track.stamp_ns)
        return track_error(track, PoseTrack(track.stamp_ns, x, y, th)).ape_rmse_m

    as_matched = slam.close_loops(scans, match)
    assert as_matched.widened == 1.0  # the drift within the bounds: one search
    # two degrees a metre: the loops come back some 20 degrees turned, past the coarse
    # search's 15, and the track closed within the bounds fails its check
    drifted = dataclasses.replace(match, track=_bent(match.track, math.radians(2.0)))
    result = slam.close_loops(scans, drifted)
    assert result.widened > 1.0
    assert result.free_space is not None and not result.free_space.fails
    assert result.closures
    assert ape(result.track) < 0.3 * ape(drifted.track)
