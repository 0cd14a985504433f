"""Global consistency without ground truth: a track scored on the revisits the scans found.

A pose graph's loop-closure search (:mod:`gridmap_cli.poses.correction.loop_closure`) finds,
from the scans alone, pairs of keyframes taken at the same place far apart along the path, and
registers one's submap onto the other's: the relative pose of the two scans, as the scans see
it. Those are relations like the SLAM benchmark's (scan-matched, then checked by hand), found
by the log itself. Any track (the odometry, the scan-matched one, the graph's) can be scored on
them the way :func:`gridmap_cli.evaluation.relations.score_track` scores a track on a relations
file: a track that drifts, or that is crisp locally but bent as a whole, puts the two visits of
a place apart, and fails the relations that span the drift or the bend.

**One number, in the map's units.** For a relation between the scans at ``t1`` and ``t2``, the
track's relative pose and the registered one differ by ``E`` (the scan at ``t2`` as the track
places it, seen from where the registration puts it). Each echo ``p`` of that scan lands
``|E p - p|`` away from where the first visit saw the same wall; the relation's *displacement*
is the root mean square of that over the scan's echoes (translation and rotation in one length,
with no weight to choose). The score is the **mean** over the relations; the median is reported
beside it, as the typical place.

**Why the mean.** A median ignores how far apart the visits are on every relation past the
middle one: a track broken at one place (a heading lost in a gap of the odometry), whose break
fewer than half of the relations straddle, scores as if it were whole, although every pose after
the break is off. The mean counts the break by its size times the share of relations across it.
It needs no guard against a false closure to rank the maps of one log: a relation's displacement
is the root mean square distance between the scan's echoes placed by the track and placed by the
registration, a distance between point sets, so on any relation two tracks' displacements
differ by at most the distance between the two tracks' placements of that scan (the triangle
inequality), whatever the relation's own error. A false closure shifts the difference of two
tracks' means by no more than the tracks' own disagreement on it, over the number of relations.
It does move the mean itself, so a mean compares the maps of one log, not two logs.

**The graph's own track is not scored on what it was fitted to.** Its optimum was solved with
these closures as edges, so its fit to them is a residual, not a check. Each closure is instead
predicted by the graph solved without its fold (:data:`FOLDS` folds, every fifth closure in the
order they were accepted), from the same start: the graph is scored on relations it did not
see, as the other tracks are. The folds interleave, so a revisit caught by several closures
keeps the others; what is checked is that the closures agree with one another through the
graph. A loop closed by one closure alone is predicted without it, by the scan-matched drift.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import relative_poses, wrap_angle
from gridmap_cli.poses.sync import interpolate_pose
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import RobotDescription

if TYPE_CHECKING:
    from gridmap_cli.poses.correction.slam import SlamResult

F64 = npt.NDArray[np.float64]

#: Folds the graph's closures are held out in: each fold is re-solved without a fifth of them,
#: few enough to cost a handful of solves, enough that most closures keep their neighbours.
FOLDS = 5


@dataclass(frozen=True)
class Revisits:
    """Relations found by the scans, shape (R,) each: the stamps (ns) of the two scans, the
    pose at ``t2_ns`` in the robot's frame at ``t1_ns`` (metres, radians), and the echoes of
    the scan at ``t2_ns`` in its own frame summed up: their mean point (R, 2) and mean squared
    distance from the robot (R,), m^2. ``predicted`` (R, 3): the relative pose the pose graph
    gives each relation with its fold held out (None: not computed)."""

    t1_ns: npt.NDArray[np.int64]
    t2_ns: npt.NDArray[np.int64]
    relative: F64
    echo_mean_m: F64
    echo_square_m2: F64
    predicted: F64 | None = None

    def __len__(self) -> int:
        return int(self.t1_ns.shape[0])


@dataclass(frozen=True)
class RevisitScore:
    """A track on :class:`Revisits`: ``relations`` scored (``skipped``: a stamp outside the
    track), the median and mean echo displacement (m), the mean translational (m) and rotational
    (deg) error; ``held_out``: the track is the pose graph's, predicted fold by fold."""

    relations: int
    skipped: int
    median_m: float
    mean_m: float
    trans_mean_m: float
    rot_mean_deg: float
    held_out: bool

    def as_dict(self) -> dict[str, Any]:
        def r(v: float, digits: int = 4) -> float | None:
            return None if math.isnan(v) else round(v, digits)

        return {
            "relations": self.relations,
            "skipped": self.skipped,
            "median_m": r(self.median_m),
            "mean_m": r(self.mean_m),
            "trans_mean_m": r(self.trans_mean_m),
            "rot_mean_deg": r(self.rot_mean_deg, 3),
            "held_out": self.held_out,
        }


def echo_displacement(error: F64, echo_mean_m: F64, echo_square_m2: F64) -> F64:
    """Root mean square of ``|E p - p|`` over each scan's echoes ``p`` (R,), metres: ``error``
    (R, 3) the poses ``E``, the echoes given by their mean point (R, 2) and mean squared
    distance (R,). With ``E p = R p + t``: ``mean |t + (R - I) p|^2 = |t|^2 + 2 t.(R - I)
    mean(p) + 2 (1 - cos theta) mean |p|^2``."""
    t = error[:, :2]
    c, s = np.cos(error[:, 2]), np.sin(error[:, 2])
    mx, my = echo_mean_m[:, 0], echo_mean_m[:, 1]
    turned = np.column_stack([(c - 1) * mx - s * my, s * mx + (c - 1) * my])
    square = (t**2).sum(axis=1) + 2 * (t * turned).sum(axis=1) + 2 * (1 - c) * echo_square_m2
    out: F64 = np.sqrt(np.maximum(square, 0.0))
    return out


def score_relative(estimated: F64, revisits: Revisits, held_out: bool = False) -> RevisitScore:
    """Score relative poses (R, 3), a track's for each relation (NaN rows: not covered)."""
    ok = ~np.isnan(estimated).any(axis=1)
    count = int(ok.sum())
    if count == 0:
        nan = math.nan
        return RevisitScore(0, len(revisits), nan, nan, nan, nan, held_out)
    error = relative_poses(revisits.relative[ok], estimated[ok])
    error[:, 2] = wrap_angle(error[:, 2])
    moved = echo_displacement(error, revisits.echo_mean_m[ok], revisits.echo_square_m2[ok])
    return RevisitScore(
        relations=count,
        skipped=len(revisits) - count,
        median_m=float(np.median(moved)),
        mean_m=float(moved.mean()),
        trans_mean_m=float(np.hypot(error[:, 0], error[:, 1]).mean()),
        rot_mean_deg=float(np.degrees(np.abs(error[:, 2])).mean()),
        held_out=held_out,
    )


def score_track(track: PoseTrack, revisits: Revisits) -> RevisitScore:
    """Score ``track`` (any frame) on ``revisits``: its poses at the relations' stamps,
    interpolated; a relation with a stamp outside the track is skipped."""
    x1, y1, t1, ok1 = interpolate_pose(track, revisits.t1_ns)
    x2, y2, t2, ok2 = interpolate_pose(track, revisits.t2_ns)
    estimated = relative_poses(np.column_stack([x1, y1, t1]), np.column_stack([x2, y2, t2]))
    estimated[~(ok1 & ok2)] = np.nan
    return score_relative(estimated, revisits)


def graph_revisits(
    slam: SlamResult, log: RangeLog, robot: RobotDescription | None, hold_out: bool = True
) -> Revisits | None:
    """The accepted loop closures of ``slam`` as :class:`Revisits`, the echoes read from the
    laser scans of ``log`` (the log the graph was solved from); with ``hold_out``, each one's
    prediction by the graph solved without its fold. None without a closure."""
    if not slam.closures:
        return None
    from gridmap_cli.poses.correction.scan_match import ScanMatchParams, laser_scans
    from gridmap_cli.poses.sync import sensors_for_log

    node_ns = slam.track.stamp_ns[slam.keyframes]
    i = np.array([c.i for c in slam.closures], dtype=np.intp)
    j = np.array([c.j for c in slam.closures], dtype=np.intp)
    relative = np.array([(c.dx_m, c.dy_m, c.dtheta_rad) for c in slam.closures])
    scans = laser_scans(log, sensors_for_log(log, robot), ScanMatchParams())
    at = np.clip(np.searchsorted(scans.stamp_ns, node_ns[j]), 0, len(scans) - 1)
    mean = np.zeros((len(j), 2))
    square = np.zeros(len(j))
    for k, s in enumerate(at.tolist()):
        points = scans.points[s]
        if scans.stamp_ns[s] == node_ns[j[k]] and len(points):
            mean[k] = points.mean(axis=0)
            square[k] = float((points**2).sum(axis=1).mean())
    revisits = Revisits(node_ns[i], node_ns[j], relative, mean, square)
    if hold_out:
        revisits = dataclasses.replace(revisits, predicted=held_out_relative(slam))
    return revisits


def held_out_relative(slam: SlamResult, folds: int = FOLDS) -> F64 | None:
    """Per accepted closure (R, 3): node ``j``'s pose in node ``i``'s frame on the graph solved
    without the closure's fold (every ``folds``-th closure), from the graph's own start. None
    when the result keeps no graph."""
    from gridmap_cli.poses.correction.pose_graph import PoseGraph

    graph = slam.graph
    if graph is None:
        return None
    sequential = [e for e in graph.edges if not e.closure]
    closures = [e for e in graph.edges if e.closure]
    ends = {(e.i, e.j): k for k, e in enumerate(closures)}
    predicted = np.full((len(closures), 3), np.nan)
    for fold in range(min(folds, len(closures))):
        kept = [e for k, e in enumerate(closures) if k % folds != fold]
        solved = PoseGraph(graph.initial.copy(), sequential + kept, graph.cauchy_k).optimise()
        out = np.arange(fold, len(closures), folds)
        pairs = np.array([(closures[k].i, closures[k].j) for k in out])
        predicted[out] = relative_poses(solved[pairs[:, 0]], solved[pairs[:, 1]])
    order = [ends.get((c.i, c.j)) for c in slam.closures]
    if any(k is None for k in order):
        return None
    return predicted[np.array(order, dtype=np.intp)]


def map_revisits(
    revisits: Revisits | None, track: PoseTrack, graph_track: bool
) -> RevisitScore | None:
    """The score of a map's ``track`` on ``revisits``: the held-out predictions when the track
    is the graph's own (``graph_track``) and they were computed, else the track itself."""
    if revisits is None:
        return None
    if graph_track and revisits.predicted is not None:
        return score_relative(revisits.predicted, revisits, held_out=True)
    return score_track(track, revisits)
