"""``--pose slam``: the scan-matched track with loop closures, optimised as a pose graph.

1. The scan matcher (:mod:`.scan_match`) gives every scan a locally consistent pose.
2. Keyframes are the scans where the robot has moved ``keyframe_m`` or turned ``keyframe_rad``
   since the last one; consecutive keyframes are joined by the scan-matched relative pose, with a
   standard deviation growing with the distance between them (larger where a scan fell back to
   odometry); a step whose match and odometry disagree far beyond the log's usual keeps both
   ends, and the graph chooses where it judges the closures (:func:`.degeneracy.second_ends`).
3. Loop closures (:mod:`.loop_closure`) are sought among keyframes near each other in the current
   estimate but far along the path, verified by registration, and added with a robust kernel,
   shorter loops first: the graph (:mod:`.pose_graph`, gtsam) is solved after each doubling of
   loop length, so a long loop is offered and guessed from a track its shorter loops
   corrected. Closures whose residual stays large are then dropped (the consistency check)
   and the search is repeated from the better estimate, for up to ``rounds`` rounds.
4. A track that fails its free-space check (:mod:`.free_space`: a loop closed wrongly or
   missed) tries the loops that only candidates under the inlier gate would close, judged on
   what their targets saw (:mod:`.overlap`), a loop at a time, keeping each that leaves fewer
   of the track's revisits contradicting; where it still fails, or fails the check's wide
   look, or its closures corrected the drift by as much as the search allowed, steps 3-4 run
   again with the search's bounds on the drift wider (:mod:`.repair`).
5. Every scan's pose is the scan-matched one carried by the correction of the keyframes around it
   (interpolated in time); every other pose of the log likewise (:func:`.corrected_track`).

The honesty check: the accepted closures are scored on the odometry and on the optimised track;
when the optimised track does not agree with them better than the odometry does, or no loop
closed, :attr:`SlamResult.warning` says so.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.poses.correction.degeneracy import second_ends, weak_stretch
from gridmap_cli.poses.correction.free_space import FreeSpaceCheck, check_poses
from gridmap_cli.poses.correction.loop_closure import (
    Closure,
    ClosureParams,
    Submaps,
    anchors,
    candidates,
    near_ends,
    path_length,
    relative,
    verify,
)
from gridmap_cli.poses.correction.pose_graph import (
    Edge,
    PoseGraph,
    edge_residuals,
    largest_bend,
)
from gridmap_cli.poses.correction.repair import (
    PASSES,
    WIDER_SEARCH,
    agreeing,
    carried,
    closure_edge,
    doubted_loops,
    drifted,
    partial_loops,
    solved,
    standing,
    wider,
    with_closures,
)
from gridmap_cli.poses.correction.scan_match import (
    FALLBACK,
    Progress,
    ScanMatch,
    ScanMatchParams,
    Scans,
    corrected_track,
    log_scans,
    match_scans,
)
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import RobotDescription

FloatArray = npt.NDArray[np.float64]

#: The scan matcher's settings under the graph: GICP's correspondences cut at 0.5 m instead of
#: the open-loop matcher's 1 m. With loop closures to take out the drift, the matcher is wanted
#: precise more than forgiving; measured on the benchmark relations, 0.3 to 0.7 m all beat 1 m
#: on the three shared logs (Intel 0.045 -> 0.043 m, ACES 0.046 -> 0.044, Freiburg 079 0.040
#: -> 0.036) with fewer fallbacks, while the open-loop track alone drifts further on ACES.
SLAM_MATCH = ScanMatchParams(correspondence_m=0.5)

#: A sequential edge bent by more than this many of its standard deviations on the optimised
#: track warns: a false closure folding the map bends one this far, and so can true closures
#: taking out a scan-matching slip, so it asks for a look rather than rejecting the track.
BEND_WARN_SIGMA = 5.0


@dataclass(frozen=True)
class SlamParams:
    """Keyframes, edge noise and the closure search; metres and radians."""

    keyframe_m: float = 0.5
    keyframe_rad: float = math.radians(20.0)
    sigma_xy_m: float = 0.02
    sigma_xy_per_m: float = 0.02
    sigma_theta_rad: float = math.radians(0.5)
    sigma_theta_per_m: float = math.radians(0.5)
    fallback_scale: float = 5.0
    #: the heading error (1 sigma) of the odometry per radian it turned, where a scan took the
    #: odometry's step: a fifth of the turn, tighter than ROS amcl's default motion noise (its
    #: alpha1 of 0.2 is a variance coefficient, a sigma of 0.45 per radian)
    fallback_sigma_theta_per_rad: float = 0.2
    #: along a featureless corridor an edge holds only the odometry (the match said nothing
    #: there): this much more sigma per metre along it, loose enough that a closure stretches
    #: the corridor rather than bending the track
    degenerate_sigma_per_m: float = 0.5
    closure_sigma_xy_m: float = 0.05
    closure_sigma_theta_rad: float = math.radians(1.0)
    reject_m: float = 0.3
    reject_rad: float = math.radians(5.0)
    rounds: int = 3
    covariance: bool = False
    closure: ClosureParams = field(default_factory=ClosureParams)


@dataclass(frozen=True)
class SlamResult:
    """The optimised track and how it was obtained.

    ``match``: the scan match with its track replaced by the optimised scan poses;
    ``scan_matched``: the scan match as it was. ``keyframes`` (K,): scan index of each node;
    ``poses`` (K, 3) the optimised keyframe poses; ``covariance`` (K, 3, 3) their marginal
    covariances (node frame; None unless asked). ``closures``: the accepted closures.
    ``bend_sigma``: the largest error of a sequential (scan-matching) edge on the optimised
    track, in its own standard deviations: how far the closures bend the scan-matched track.
    """

    match: ScanMatch
    scan_matched: ScanMatch
    keyframes: npt.NDArray[np.intp]
    poses: FloatArray
    covariance: FloatArray | None
    closures: list[Closure]
    candidates: int
    rejected: int
    dropped: int
    odometry_residual_m: float
    residual_m: float
    seconds: float
    #: the optimised graph, for its marginals and draws (:mod:`.pose_belief`)
    graph: PoseGraph | None = None
    bend_sigma: float = 0.0
    #: the scans matched, one per pose of :attr:`track` (for checks of the track against them)
    scans: Scans | None = None
    #: accepted closures under the inlier gate, kept where the track failed its free-space
    #: check without them (:func:`.repair.partial_loops`)
    partial: int = 0
    #: the free-space check of :attr:`track`
    free_space: FreeSpaceCheck | None = None
    #: how many times wider the closure search's bounds on the drift were than asked
    #: (:data:`.repair.WIDER_SEARCH`); 1: as asked
    widened: float = 1.0
    #: why the search as asked was searched again wider, kept or not: its track failed the
    #: "check" or the "wide look", or it had "drift"ed as far as it allowed; None: it was not
    widened_for: str | None = None

    @property
    def track(self) -> PoseTrack:
        """The optimised pose of every scan."""
        return self.match.track

    @property
    def warning(self) -> str | None:
        """Why the track may be no better than the scan-matched or the odometry one."""
        if not self.closures:
            return "no loop closed: the track is the scan-matched one, with its drift"
        if self.residual_m >= self.odometry_residual_m:
            return (
                f"the optimised track fits its loop closures no better than the odometry "
                f"({self.residual_m:.3f} m against {self.odometry_residual_m:.3f} m)"
            )
        if self.bend_sigma > BEND_WARN_SIGMA:
            return (
                f"the loop closures bend the scan-matched track by {self.bend_sigma:.1f} "
                "standard deviations somewhere: a closure may be false, check the map"
            )
        return None

    def summary(self) -> dict[str, object]:
        """Counts and residuals for people and JSON."""
        return {
            "keyframes": len(self.keyframes),
            "candidates": self.candidates,
            "closures_accepted": len(self.closures),
            "closures_rejected": self.rejected + self.dropped,
            "closures_dropped_by_consistency": self.dropped,
            "closures_of_partial_overlap": self.partial,
            "closure_search_widened": self.widened,
            "closure_search_widened_for": self.widened_for,
            "closure_residual_m": round(self.residual_m, 4),
            "closure_residual_odometry_m": round(self.odometry_residual_m, 4),
            "sequential_bend_sigma": round(self.bend_sigma, 2),
            "fallbacks": self.scan_matched.fallbacks,
            "scan_match": self.scan_matched.summary(),
            "seconds": round(self.seconds, 3),
            "warning": self.warning,
        }


def keyframes(poses: FloatArray, params: SlamParams) -> npt.NDArray[np.intp]:
    """Indices of the keyframe poses (N, 3): the first, then each far enough from the last."""
    keep = [0]
    for k in range(1, len(poses)):
        last = poses[keep[-1]]
        turn = abs(math.remainder(float(poses[k, 2] - last[2]), 2 * math.pi))
        if math.hypot(*(poses[k, :2] - last[:2])) >= params.keyframe_m or turn >= (
            params.keyframe_rad
        ):
            keep.append(k)
    if keep[-1] != len(poses) - 1:
        keep.append(len(poses) - 1)
    return np.array(keep, dtype=np.intp)


def sequential_edges(
    local: FloatArray,
    status: npt.NDArray[np.int8],
    nodes: npt.NDArray[np.intp],
    p: SlamParams,
    weak: FloatArray | None = None,
    others: list[tuple[float, float] | None] | None = None,
) -> list[Edge]:
    """Edges between consecutive keyframes from the scan-matched poses ``local`` (S, 3); where
    scans between them were degenerate (``weak`` (S, 2), the scan matcher's weak axes), the
    edge is looser along the corridor by ``degenerate_sigma_per_m`` per metre along it; each
    of ``others`` not None makes its step's edge two-way (:func:`.degeneracy.second_ends`)."""
    edges = []
    for a in range(len(nodes) - 1):
        s, t = int(nodes[a]), int(nodes[a + 1])
        dx, dy, dth = relative(local, t, s)
        dist = math.hypot(dx, dy)
        fell = np.flatnonzero(status[s + 1 : t + 1] == FALLBACK) + s + 1
        scale = p.fallback_scale if len(fell) else 1.0
        # a scan that fell back took the odometry's turn, whose error grows with the turn
        turned = float(np.abs(wrap_angle(local[fell, 2] - local[fell - 1, 2])).sum())
        weak_m, axis = weak_stretch(local, weak, s, t) if weak is not None else (0.0, (1.0, 0.0))
        edges.append(
            Edge(
                a, a + 1, dx, dy, dth,
                scale * (p.sigma_xy_m + p.sigma_xy_per_m * dist),
                scale * (p.sigma_theta_rad + p.sigma_theta_per_m * dist)
                + p.fallback_sigma_theta_per_rad * turned,
                weak_sigma_m=p.degenerate_sigma_per_m * weak_m, weak_axis=axis,
                other=None if others is None else others[a],
            )
        )  # fmt: skip
    return edges


#: What :func:`optimise_with_closures` returns.
_Optimised = tuple[
    npt.NDArray[np.intp], FloatArray, PoseGraph, list[Closure], int, int, int, FreeSpaceCheck | None
]


def optimise_with_closures(
    scans: Scans, match: ScanMatch, params: SlamParams, progress: Progress | None = None
) -> _Optimised:
    """Keyframes, their optimised poses, the graph, accepted closures, the counts of candidates
    tried, rejected by verification and dropped by the consistency check or as doubted
    (:func:`.repair.doubted_loops`), and the free-space check of the track. ``progress`` is called
    after each round with ``("loop closures", rounds done, rounds)``."""
    m = match.track
    local = np.column_stack([m.x_m, m.y_m, m.theta_rad])
    nodes = keyframes(local, params)
    odo = np.column_stack([match.odometry.x_m, match.odometry.y_m, match.odometry.theta_rad])
    others = second_ends(local, odo, nodes, match.distance_scale)
    edges = sequential_edges(local, match.status, nodes, params, match.weak_axis, others)
    graph = PoseGraph(local[nodes].copy(), edges)
    submaps = Submaps(scans.points, local, nodes, params.closure)
    estimate = graph.initial.copy()
    tried: set[tuple[int, int]] = set()
    accepted: dict[tuple[int, int], Closure] = {}
    partial: list[Closure] = []
    rejected = dropped = 0
    path = path_length(estimate)
    c = params.closure
    # closures are tested between keyframes decimate_m of path apart: a keyframe's submap
    # spans submap_m of path, so the ones between add tests of nearly the same scans
    spots = anchors(path, c.decimate_m)
    for done in range(params.rounds):
        if progress is not None:
            progress("loop closures", done, params.rounds)
        new = 0
        # the path positions of the accepted closures' ends: a candidate next to one (both
        # ends within decimate_m) adds little; one within coarse_link_m of a closure found
        # this round is on a loop already caught, so no coarse search for it
        ends = np.array([(path[k[0]], path[k[1]]) for k in accepted]).reshape(-1, 2)
        fresh: list[tuple[float, float]] = []
        searched: list[tuple[float, float]] = []  # coarse searches that found nothing
        # shorter loops first, the graph solved after each length: a long loop's candidates
        # are then chosen and guessed from a track its shorter loops have already corrected
        # (in the round's first estimate a drifted stretch's nearest anchors are often its
        # neighbours', whose submaps barely overlap its own)
        tiers = by_gap(candidates(estimate, spots, c, targets=spots), path, c.min_path_m)
        length = -1
        while any(t > length for t in tiers):
            length = min(t for t in tiers if t > length)
            added = 0
            for i, j in tiers[length]:
                if (i, j) in tried or near_ends(ends, path[i], path[j], c.decimate_m):
                    continue
                tried.add((i, j))
                gap = path[i] - path[j]
                radius = min(c.max_search_m, c.min_search_m + c.drift_per_m * gap)
                coarse = not (
                    near_ends(np.array(fresh).reshape(-1, 2), path[i], path[j], c.coarse_link_m)
                    or near_ends(np.array(searched).reshape(-1, 2), path[i], path[j], c.decimate_m)
                )
                closure = verify(i, j, relative(estimate, i, j), submaps, radius, coarse, partial)
                if closure is None:
                    rejected += 1
                    if coarse:
                        searched.append((path[i], path[j]))
                    continue
                # the closure's target may be another keyframe than the one offered
                i, j = closure.i, closure.j
                accepted[(i, j)] = closure
                ends = np.vstack([ends, [(path[i], path[j])]])
                fresh.append((path[i], path[j]))
                added += 1
            if added:
                # the next, longer loops guessed from this solution; closures judged, and
                # two-way edges' ends chosen, below
                with_closures(graph, accepted.values(), params)
                estimate = graph.optimise(estimate, choose=False)
                new += added
                tiers = by_gap(candidates(estimate, spots, c, targets=spots), path, c.min_path_m)
        if new == 0:
            break
        estimate, drops = solved(graph, estimate, accepted, params)
        dropped += drops
    check = None
    if partial:
        estimate, check = partial_loops(
            scans, match, nodes, graph, estimate, accepted, partial, submaps, params
        )
    held = len(accepted)
    estimate, check = doubted_loops(
        scans, match, nodes, graph, estimate, accepted, submaps, params, check
    )
    dropped += held - len(accepted)
    if progress is not None:
        progress("loop closures", params.rounds, params.rounds)
    return nodes, estimate, graph, list(accepted.values()), len(tried), rejected, dropped, check


def by_gap(
    pairs: list[tuple[int, int]], path: FloatArray, shortest_m: float
) -> dict[int, list[tuple[int, int]]]:
    """``pairs`` (i, j) grouped by the path between them, each group twice the length of the
    one before from ``shortest_m`` on: group k holds the gaps from ``shortest_m`` 2^k up to
    twice that; each group in its given order."""
    tiers: dict[int, list[tuple[int, int]]] = {}
    for i, j in pairs:
        gap = max(float(path[i] - path[j]), shortest_m)
        tiers.setdefault(int(math.log2(gap / shortest_m)), []).append((i, j))
    return tiers


def slam_scans(
    scans: Scans,
    odometry: PoseTrack,
    params: SlamParams | None = None,
    match_params: ScanMatchParams | None = None,
    progress: Progress | None = None,
) -> SlamResult:
    """Scan-match ``scans`` seeded by ``odometry``, close loops, optimise; see the module.
    ``progress`` is called with (stage, done, total) as each stage moves on."""
    started = time.perf_counter()
    match = match_scans(scans, odometry, match_params or SLAM_MATCH, progress)
    return close_loops(scans, match, params, progress, started)


def close_loops(
    scans: Scans,
    match: ScanMatch,
    params: SlamParams | None = None,
    progress: Progress | None = None,
    started: float | None = None,
) -> SlamResult:
    """The pose graph on the scan match ``match`` of ``scans``: steps 2-5 of the module, the
    closure search widened (:data:`.repair.WIDER_SEARCH`) while the track fails its free-space
    check or its wide look, or has drifted past the search (:func:`.repair.drifted`); a wider
    track is kept where it stands better by the two (:func:`.repair.standing`), or, searched
    for the drift alone, as well and at more revisits that agree. ``started``: the clock
    (``time.perf_counter``) the result's seconds count from (default: now)."""
    params = params or SlamParams()
    started = time.perf_counter() if started is None else started
    found, track, check = _searched(scans, match, params, progress)
    widened = 1.0
    stands = standing(track, scans.points, check)
    drift = drifted(match.track, found[0], found[3], params.closure)
    searched = stands != PASSES or drift
    why = ("drift", "wide look", "check")[stands[0]] if searched else None
    for factor in WIDER_SEARCH:
        if stands == PASSES and not drift:
            break
        wide = dataclasses.replace(params, closure=wider(params.closure, factor))
        again = _searched(scans, match, wide, _named(progress, f"{factor:g}x wider"))
        stands_again = standing(again[1], scans.points, again[2])
        # a track that stands no better is kept for the drift only, where more revisits agree
        if stands_again < stands or (
            drift and stands_again == stands and agreeing(again[2]) > agreeing(check)
        ):
            (found, track, check), widened, stands = again, factor, stands_again
            drift = drifted(match.track, found[0], found[3], wide.closure)
    nodes, poses, graph, closures, tried, rejected, dropped, _ = found
    partial = sum(c.inlier_fraction < params.closure.min_inlier_fraction for c in closures)
    odo = match.odometry
    odo_nodes = np.column_stack([odo.x_m, odo.y_m, odo.theta_rad])[nodes]
    closure_edges = [closure_edge(c, params) for c in closures]
    before = edge_residuals(odo_nodes, closure_edges)
    after = edge_residuals(poses, closure_edges)
    covariance = graph.marginals(poses) if params.covariance else None
    sequential = [e for e in graph.edges if not e.closure]
    bend_sigma = largest_bend(poses, sequential)
    return SlamResult(
        match=dataclasses.replace(match, track=track),
        scan_matched=match,
        keyframes=nodes,
        poses=poses,
        covariance=covariance,
        closures=closures,
        candidates=tried,
        # a closure under the gate that a failing track kept was counted rejected when tried
        rejected=rejected - partial,
        dropped=dropped,
        odometry_residual_m=float(before[:, 0].mean()) if len(before) else float("nan"),
        residual_m=float(after[:, 0].mean()) if len(after) else float("nan"),
        seconds=time.perf_counter() - started,
        graph=graph,
        bend_sigma=bend_sigma,
        scans=scans,
        partial=partial,
        free_space=check,
        widened=widened,
        widened_for=why,
    )


def _searched(
    scans: Scans, match: ScanMatch, params: SlamParams, progress: Progress | None
) -> tuple[_Optimised, PoseTrack, FreeSpaceCheck]:
    """:func:`optimise_with_closures`, every scan's pose on its track, and the track's
    free-space check (the graph's own where it took one)."""
    found = optimise_with_closures(scans, match, params, progress)
    track = carried(match, found[0], found[1])
    return found, track, found[7] or check_poses(track, scans.points)


def _named(progress: Progress | None, what: str) -> Progress | None:
    """``progress`` with ``what`` added to each stage's name (a stage run again)."""
    if progress is None:
        return None
    given = progress
    return lambda stage, done, total: given(f"{stage}, {what}", done, total)


def slam_log(
    log: RangeLog,
    robot: RobotDescription | None,
    params: SlamParams | None = None,
    progress: Progress | None = None,
) -> SlamResult:
    """:func:`slam_scans` on the laser scans of ``log`` within its odometry's time span."""
    return slam_scans(log_scans(log, robot, SLAM_MATCH), log.poses, params, SLAM_MATCH, progress)


def slam_corrected_log(
    log: RangeLog,
    robot: RobotDescription | None,
    params: SlamParams | None = None,
    progress: Progress | None = None,
) -> tuple[RangeLog, SlamResult]:
    """``log`` with its poses replaced by the optimised track, and the result."""
    result = slam_log(log, robot, params, progress)
    return dataclasses.replace(log, poses=corrected_track(log.poses, result.match)), result
