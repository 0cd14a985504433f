"""What the pose graph tries when its track fails its free-space check, and the pieces it
shares with :mod:`.slam`: a closure's edge and every scan's pose carried by the keyframes.

A track fails the check (:mod:`.free_space`) when the places the robot came back to contradict
what it saw there the first time: a loop closed wrongly, or missed. Only then, so that no
passing track moves:

- :func:`partial_loops` tries the loops that closures under the inlier gate would close
  (:mod:`.overlap`), keeping each that leaves fewer revisits contradicting;
- where the track still fails, the closure search runs again with its bounds on the drift
  :data:`WIDER_SEARCH` times as wide (:func:`wider`): the scan matcher may have drifted further
  before the robot came back than the bounds allow (a campus, a laser that sees little), so the
  true closures were never offered or their coarse search looked too narrowly, while a
  look-alike place within the bounds could pass. The first wider track that passes is kept,
  else the one with the smallest share of its revisits contradicting, the search as asked
  included (:func:`.slam.close_loops`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Protocol

import numpy as np
import numpy.typing as npt

from gridmap_cli.poses.correction.carry import carry
from gridmap_cli.poses.correction.free_space import FreeSpaceCheck, check_poses
from gridmap_cli.poses.correction.loop_closure import (
    Closure,
    ClosureParams,
    Submaps,
    by_loop,
    holds_where_seen,
    path_length,
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
        graph.edges = [e for e in graph.edges if not e.closure] + [
            closure_edge(k, params) for k in trial.values()
        ]
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
    graph.edges = [e for e in graph.edges if not e.closure] + [
        closure_edge(k, params) for k in accepted.values()
    ]
    return estimate, now


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
