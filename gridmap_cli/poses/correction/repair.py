"""What the pose graph tries when its track fails its free-space check, and the pieces it
shares with :mod:`.slam`: a closure's edge, the graph solved with its closures, and every
scan's pose carried by the keyframes.

A track fails the check (:mod:`.free_space`) when the places the robot came back to contradict
what it saw there the first time: a loop closed wrongly, or missed. Only then, so that no
passing track moves:

- :func:`partial_loops` tries the loops that closures under the inlier gate would close
  (:mod:`.overlap`), keeping each that leaves fewer revisits contradicting;
- :func:`doubted_loops` takes out, a loop at a time, the accepted closures that do not hold on
  their target's view, keeping each loop out that leaves fewer revisits contradicting: a
  look-alike found near a guess the drift carried off passes the gate and the far closures'
  test beyond chance, but puts more of what its target saw in the target's free space than
  the log's own revisits do;
- where the track still fails, or fails the check's wide look, the closure search runs again
  with its bounds on the drift :data:`WIDER_SEARCH` times as wide (:func:`wider`): the scan
  matcher may have drifted further before the robot came back than the bounds allow (a campus,
  a laser that sees little), so the true closures were never offered or their coarse search
  looked too narrowly, while a look-alike place within the bounds could pass. A wider track is
  kept where it stands better by the two looks (:func:`standing`), the search as asked
  included (:func:`.slam.close_loops`).

A track that passes both can still have been searched too narrowly: where the closures it
accepted turned the scan-matched track by as much as the search's heading window allowed
(:func:`drifted`), the drift the log has is the bounds' own size, and the loops that drifted
further were never offered; a loop guessed tens of metres off may then be closed onto a
look-alike place, leaving a track bent but consistent where it comes back (its revisits few).
The search runs wider there too, and a wider track that stands as well is kept where more of
its revisits agree (:func:`agreeing`): the loops it closed brought the robot back to places its
scans confirm.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from typing import Protocol

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.poses.correction.carry import carry
from gridmap_cli.poses.correction.free_space import FreeSpaceCheck, check_poses, verdict
from gridmap_cli.poses.correction.loop_closure import (
    Closure,
    ClosureParams,
    Submaps,
    holds_where_seen,
    near_ends,
    path_length,
    relative,
)
from gridmap_cli.poses.correction.pose_graph import (
    KERNEL_STAGES,
    Edge,
    PoseGraph,
    edge_residuals,
)
from gridmap_cli.poses.correction.scan_match import ScanMatch, Scans
from gridmap_cli.records import PoseTrack

FloatArray = npt.NDArray[np.float64]


class GraphParams(Protocol):
    """What the repairs read of the graph's settings (:class:`.slam.SlamParams`)."""

    @property
    def closure(self) -> ClosureParams: ...
    @property
    def closure_sigma_xy_m(self) -> float: ...
    @property
    def closure_sigma_theta_rad(self) -> float: ...
    @property
    def reject_m(self) -> float: ...
    @property
    def reject_rad(self) -> float: ...


#: How many times wider, in turn, the closure search's bounds on the drift are on a track that
#: still fails its check: each doubling, as long as the track fails.
WIDER_SEARCH = (2.0, 4.0)


def wider(c: ClosureParams, factor: float) -> ClosureParams:
    """The closure search with its bounds on the drift ``factor`` times as wide: the drift
    rule's growth per metre and its cap (the coarse search's translation window), and the
    coarse search's heading window (at most all round)."""
    return dataclasses.replace(
        c,
        drift_per_m=factor * c.drift_per_m,
        max_search_m=factor * c.max_search_m,
        coarse_window_rad=min(math.pi, factor * c.coarse_window_rad),
    )


#: How a track stands that passes its free-space check and the check's wide look
#: (:func:`standing`).
PASSES = (0, 0.0)


def standing(
    track: PoseTrack, points: list[FloatArray], check: FreeSpaceCheck
) -> tuple[int, float]:
    """How ``track`` stands by its free-space check ``check`` and the wide look (the order of
    the tuples, lower better): :data:`PASSES`; (1, the wide look's share of contradicting
    revisits) failing that only; (2, the check's share) failing the check."""
    check, wide, _ = verdict(track, points, check)
    if check.fails:
        return 2, check.share
    assert wide is not None  # the verdict takes its wide look wherever the check passes
    # a check too noisy to judge (:attr:`.free_space.FreeSpaceCheck.blind`) ranks as passing:
    # the tracks are ranked by what the looks saw, and that one saw nothing
    return (1, wide.share) if wide.fails else PASSES


#: Why the closure search ran again wider (:attr:`.slam.SlamResult.widened_for`), as the
#: summaries say it.
WIDENED_FOR = {
    "check": "the track as asked failed its free-space check",
    "wide look": "the track as asked failed the check's wide look",
    "drift": "its closures showed a drift as large as the search allowed",
}


def widening(why: str | None, factor: float) -> str | None:
    """What a summary says of a closure search run again wider for ``why`` (a key of
    :data:`WIDENED_FOR`), the track kept searched ``factor`` times as wide; None where it was
    not run again."""
    if why is None:
        return None
    kept = f"kept {factor:g} times as wide" if factor > 1 else "kept as asked"
    return f"the closure search run again wider ({WIDENED_FOR[why]}), {kept}"


def agreeing(check: FreeSpaceCheck) -> int:
    """The revisits of a checked track that do not contradict."""
    return check.revisits - check.contradicting


def drifted(
    track: PoseTrack, nodes: npt.NDArray[np.intp], closures: list[Closure], c: ClosureParams
) -> bool:
    """Whether the accepted ``closures`` (between keyframes ``nodes``, indices into the
    scan-matched ``track``) turned that track by as much as the closure search ``c`` allowed:
    their median heading correction past half its coarse heading window. Where the drift a
    search measures is the size of its bounds, the loops that drifted further were never
    offered."""
    if not closures:
        return False
    local = np.column_stack([track.x_m, track.y_m, track.theta_rad])[nodes]
    turns = [abs(wrap_angle(k.dtheta_rad - relative(local, k.j, k.i)[2])) for k in closures]
    return bool(np.median(turns) > c.coarse_window_rad / 2)


def partial_loops(
    scans: Scans,
    match: ScanMatch,
    nodes: npt.NDArray[np.intp],
    graph: PoseGraph,
    estimate: FloatArray,
    accepted: dict[tuple[int, int], Closure],
    partial: list[Closure],
    submaps: Submaps,
    params: GraphParams,
) -> tuple[FloatArray, FreeSpaceCheck]:
    """On a track that fails its free-space check only (:mod:`.overlap`): the loops that the
    ``partial`` closures (every test passed but the inlier gate) close, none where an accepted
    closure closes one, tried a loop at a time, the largest first, while the track fails. Of
    each loop the closures that hold on their target's view are kept when the track with them
    has a smaller share of its revisits contradicting and they stay within the graph's residual
    bounds. ``accepted`` is updated; the estimate is returned, with its track's check."""
    now = check_poses(carried(match, nodes, estimate), scans.points)
    if not now.fails:
        return estimate, now
    path = path_length(estimate)
    groups = by_loop(partial, list(accepted), path, params.closure.coarse_link_m)
    held = [[k for k in group if holds_where_seen(submaps, k)] for group in groups]
    for group in sorted(held, key=len, reverse=True):
        if not now.fails or not group:
            break
        trial = dict(accepted)
        trial.update({(k.i, k.j): k for k in group})
        with_closures(graph, trial.values(), params)
        moved = graph.optimise(estimate, KERNEL_STAGES)
        res = edge_residuals(moved, [e for e in graph.edges if e.closure])
        check = check_poses(carried(match, nodes, moved), scans.points)
        better = not (
            (res[:, 0] > params.reject_m).any()
            or (res[:, 1] > params.reject_rad).any()
            or not check.share < now.share
        )
        if better:
            accepted.update(trial)
            estimate, now = moved, check
    with_closures(graph, accepted.values(), params)
    return estimate, now


def doubted_loops(
    scans: Scans,
    match: ScanMatch,
    nodes: npt.NDArray[np.intp],
    graph: PoseGraph,
    estimate: FloatArray,
    accepted: dict[tuple[int, int], Closure],
    submaps: Submaps,
    params: GraphParams,
    now: FreeSpaceCheck | None = None,
) -> tuple[FloatArray, FreeSpaceCheck]:
    """On a track that fails its free-space check only (its check ``now``, taken here where
    None): the ``accepted`` closures that do not hold on their target's view
    (:func:`.overlap.holds_in_part`), grouped by loop and taken out a loop at a time, the
    largest first, while the track fails. A loop stays out where the track without it has a
    smaller share of its revisits contradicting at no fewer than half its revisits (a track
    that opens its loops avoids the check by not coming back, not by agreeing). ``accepted`` is
    updated; the estimate is returned, with its track's check."""
    if now is None:
        now = check_poses(carried(match, nodes, estimate), scans.points)
    if not now.fails:
        return estimate, now
    doubted = [k for k in accepted.values() if not holds_where_seen(submaps, k)]
    groups = by_loop(doubted, [], path_length(estimate), params.closure.coarse_link_m)
    for group in sorted(groups, key=len, reverse=True):
        if not now.fails:
            break
        out = {(k.i, k.j) for k in group}
        trial = {key: k for key, k in accepted.items() if key not in out}
        with_closures(graph, trial.values(), params)
        moved = graph.optimise(estimate, KERNEL_STAGES)
        check = check_poses(carried(match, nodes, moved), scans.points)
        if check.share < now.share and 2 * check.revisits >= now.revisits:
            for key in out:
                del accepted[key]
            estimate, now = moved, check
    with_closures(graph, accepted.values(), params)
    return estimate, now


def solved(
    graph: PoseGraph,
    estimate: FloatArray,
    accepted: dict[tuple[int, int], Closure],
    params: GraphParams,
) -> tuple[FloatArray, int]:
    """The graph solved with the ``accepted`` closures from ``estimate``, dropping (from
    ``accepted`` too) the worst closure while any disagrees with the solution past the
    rejection bounds; the solution and how many were dropped."""
    dropped = 0
    stages = KERNEL_STAGES
    while True:
        with_closures(graph, accepted.values(), params)
        estimate = graph.optimise(estimate, stages)
        # once a closure is dropped, the estimate is already the tight kernel's optimum
        # with that one closure more: none of the rest is far from it for the wide kernels
        # to pull in, so the tight stage alone solves again, from close by
        stages = KERNEL_STAGES[-1:]
        closure_edges = [e for e in graph.edges if e.closure]
        res = edge_residuals(estimate, closure_edges)
        bad = (res[:, 0] > params.reject_m) | (res[:, 1] > params.reject_rad)
        if not bad.any():
            return estimate, dropped
        # drop the worst one at a time: one false closure can make true ones look bad
        worst = int(np.argmax(res[:, 0] / params.reject_m + res[:, 1] / params.reject_rad))
        e = closure_edges[worst]
        del accepted[(e.i, e.j)]
        dropped += 1


def by_loop(
    closures: list[Closure], accepted: list[tuple[int, int]], path: FloatArray, within_m: float
) -> list[list[Closure]]:
    """``closures`` grouped by the loop they close: one joins a group when both its ends lie
    within ``within_m`` along the path (``path`` at each node) of some member's; those with both
    ends that near an ``accepted`` pair's are left out (their loop is closed)."""
    closed = np.array([(path[i], path[j]) for i, j in accepted]).reshape(-1, 2)
    groups: list[list[Closure]] = []
    for k in sorted(closures, key=lambda k: (path[k.i], path[k.j])):
        a, b = path[k.i], path[k.j]
        if near_ends(closed, a, b, within_m):
            continue
        for group in groups:
            if near_ends(np.array([(path[g.i], path[g.j]) for g in group]), a, b, within_m):
                group.append(k)
                break
        else:
            groups.append([k])
    return groups


def with_closures(graph: PoseGraph, closures: Iterable[Closure], p: GraphParams) -> None:
    """``graph``'s closure edges made those of ``closures``, its other edges kept."""
    graph.edges = [e for e in graph.edges if not e.closure] + [closure_edge(k, p) for k in closures]


def closure_edge(c: Closure, p: GraphParams) -> Edge:
    """The graph edge of an accepted closure, with the closures' fixed noise."""
    return Edge(
        c.i, c.j, c.dx_m, c.dy_m, c.dtheta_rad, p.closure_sigma_xy_m, p.closure_sigma_theta_rad,
        closure=True,
    )  # fmt: skip


def carried(match: ScanMatch, nodes: npt.NDArray[np.intp], poses: FloatArray) -> PoseTrack:
    """Every scan's pose: its scan-matched pose carried by the keyframes' correction, blended
    between the two keyframes around it by the share of the motion (:func:`.carry.carry`)."""
    m = match.track
    x, y, th = carry(
        m.stamp_ns,
        (m.x_m, m.y_m, m.theta_rad),
        m.stamp_ns[nodes],
        (m.x_m[nodes], m.y_m[nodes], m.theta_rad[nodes]),
        (poses[:, 0], poses[:, 1], poses[:, 2]),
    )
    return PoseTrack(stamp_ns=m.stamp_ns.copy(), x_m=x, y_m=y, theta_rad=th)
