"""Loop closures between keyframes: candidates by proximity, each verified by registration.

A *candidate* pairs keyframe ``i`` with an earlier keyframe ``j`` that lies far back along the
path (``min_path_m``) but near in the current estimate: within a radius that grows with the path
between them (the scan matcher's drift, ``drift_per_m``), capped at ``max_search_m``.

A candidate is *verified* by GICP (small_gicp's, in the plane: :mod:`.sheet_gicp`) of keyframe
``i``'s local submap (its scan and its neighbours', placed by the scan-matched track, which is
locally consistent) against ``j``'s, starting from the estimate; where that start is poor, a
coarse search over offsets in x, y and heading finds a start within the search radius, and where
none registers from there, one over the whole window (``max_search_m``) places the source and
the earlier keyframe nearest that place becomes the target (:func:`_coarse`). It is *accepted*
when enough of the source's points land within ``inlier_m`` of the target
(``min_inlier_fraction``), the match constrains both directions (not a featureless corridor),
and the correction from the estimate lies within the search radius (the whole window where the
search over it found the start).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from gridmap_cli.geometry import compose, inverse, wrap_angle
from gridmap_cli.heap import release_free_memory
from gridmap_cli.poses.correction.correlative import LikelihoodGrid, SearchResult, search
from gridmap_cli.poses.correction.free_space import near_noise
from gridmap_cli.poses.correction.overlap import contradicts, holds_in_part
from gridmap_cli.poses.correction.sheet_gicp import Sheet, align, nearest_m, placed_points, sheet_of

FloatArray = npt.NDArray[np.float64]

#: Metres of travel a radian of turning counts as when submaps are cut along the path.
TURN_M = 1.0
#: Bytes of built submaps kept (the most recently used). The closure rounds come back to the
#: same submaps, most of them evicted by a round's end under a cache of a few dozen; a submap
#: holds tens of kilobytes, so a building's worth of keyframes fits (docs/slam-speed.md).
CACHED_SUBMAP_BYTES = 64 << 20


@dataclass(frozen=True)
class ClosureParams:
    """How closures are sought and judged; metres and radians. See the module text."""

    min_path_m: float = 8.0
    #: the scan matcher's drift between the two passes: a few degrees of heading over a loop
    #: of a hundred metres puts the second pass metres to the side
    drift_per_m: float = 0.05
    min_search_m: float = 1.0
    #: the window's cap, and the coarse search's window: 5 % of a 200 m revisit, what a raw
    #: full-rate log with thousands of degrees turned drifts before its loop is caught
    max_search_m: float = 10.0
    submap_m: float = 5.0
    source_m: float = 5.0
    thin_m: float = 0.2
    voxel_m: float = 0.1
    source_voxel_m: float = 0.2
    correspondence_m: float = 0.8
    inlier_m: float = 0.15
    min_inlier_fraction: float = 0.45
    degenerate_ratio: float = 0.05
    coarse_from_m: float = 1.5
    coarse_resolution_m: float = 0.1
    coarse_sigma_m: float = 0.1
    coarse_window_rad: float = math.radians(15.0)
    coarse_step_rad: float = math.radians(1.0)
    #: the correlative search only finds GICP a start; acceptance is GICP's inlier test. A
    #: true pose scores the overlap times the mean likelihood of the overlapping points, and a
    #: point within the inlier band (``inlier_m``, sigma ``coarse_sigma_m``) scores down to
    #: exp(-1.125) = 0.32, one half a cell off 0.88: a submap seen from the other direction that
    #: passes with half its points inliers scores about 0.3, and a higher gate refuses it
    coarse_min_score: float = 0.3
    coarse_points: int = 250
    coarse_range_m: float = 15.0
    #: keyframes offered per keyframe, the nearest at least 2 m of path apart: in an estimate
    #: drifted by as much as the window, the nearest keyframe is often not the one whose submap
    #: overlaps (another corridor, or the far end of the same one), and one try per keyframe
    #: leaves a loop to the few keyframes where it happens to be
    max_candidates_per_node: int = 3
    decimate_m: float = 1.0
    coarse_link_m: float = 5.0


@dataclass(frozen=True)
class Closure:
    """An accepted closure: node ``j``'s pose in node ``i``'s frame and its inlier fraction."""

    i: int
    j: int
    dx_m: float
    dy_m: float
    dtheta_rad: float
    inlier_fraction: float


def path_length(poses: FloatArray) -> FloatArray:
    """Distance travelled up to each pose, shape (N,), metres."""
    steps = np.hypot(np.diff(poses[:, 0]), np.diff(poses[:, 1]))
    return np.concatenate([[0.0], np.cumsum(steps)])


def anchors(path: FloatArray, spacing_m: float) -> npt.NDArray[np.intp]:
    """Indices into ``path`` (distance travelled at each node): the first node, then each
    ``spacing_m`` of path on from the last taken (one node per spot where the robot turned in
    place)."""
    keep = [0]
    for k in range(1, len(path)):
        if path[k] - path[keep[-1]] >= spacing_m:
            keep.append(k)
    return np.array(keep, dtype=np.intp)


def candidates(
    poses: FloatArray,
    queries: npt.NDArray[np.intp],
    params: ClosureParams,
    targets: npt.NDArray[np.intp] | None = None,
) -> list[tuple[int, int]]:
    """Pairs (i, j), j < i, of nodes near in ``poses`` (N, 3) but far along the path; ``j``
    among ``targets`` only, when given."""
    path = path_length(poses)
    tree = cKDTree(poses[:, :2] if targets is None else poses[targets, :2])
    pairs: list[tuple[int, int]] = []
    for i in queries:
        near = np.asarray(tree.query_ball_point(poses[i, :2], params.max_search_m), dtype=np.intp)
        if targets is not None:
            near = targets[near]
        gap = path[i] - path[near]
        earlier = (near < i) & (gap >= params.min_path_m)
        near, gap = near[earlier], gap[earlier]
        radius = np.minimum(params.max_search_m, params.min_search_m + params.drift_per_m * gap)
        d = np.hypot(poses[i, 0] - poses[near, 0], poses[i, 1] - poses[near, 1])
        inside = d <= radius
        near, d = near[inside], d[inside]
        taken: list[int] = []
        # nearest first, ties to the lower index
        for j in near[np.lexsort((near, d))].tolist():
            # one candidate per stretch of path: skip j near an already taken one
            if all(abs(path[j] - path[k]) > 2.0 for k in taken):
                taken.append(j)
            if len(taken) >= params.max_candidates_per_node:
                break
        pairs.extend((int(i), j) for j in taken)
    return pairs


class Submaps:
    """Each keyframe's local submap in its own frame, built on demand and kept.

    ``points``: the scans' end points (K_s, 2) in the robot frame; ``local`` (S, 3): the
    scan-matched poses of the scans; ``nodes``: the scan index of each keyframe.
    """

    def __init__(
        self,
        points: list[FloatArray],
        local: FloatArray,
        nodes: npt.NDArray[np.intp],
        params: ClosureParams,
    ) -> None:
        self.points, self.local, self.nodes, self.params = points, local, nodes, params
        self._cache: OrderedDict[tuple[int, bool], Sheet] = OrderedDict()
        self._cached_bytes = 0
        # travel along the scan-matched path, turning counted at TURN_M metres per radian
        steps = np.hypot(np.diff(local[:, 0]), np.diff(local[:, 1]))
        turns = np.abs(wrap_angle(np.diff(local[:, 2])))
        self.travel = np.concatenate([[0.0], np.cumsum(steps + TURN_M * turns)])
        self.node_path = np.concatenate([[0.0], np.cumsum(steps)])[nodes]
        self.node_travel = self.travel[nodes]
        self._grids: OrderedDict[int, LikelihoodGrid] = OrderedDict()
        self.coarse_runs = 0
        # the scan matcher's scratch, freed by now, would stay resident under the search's
        # submaps and grids (the grids live on pages of their own, :mod:`.correlative`)
        release_free_memory()

    @cached_property
    def noise(self) -> FloatArray:
        """The log's near pairs on the scan-matched track (:func:`.free_space.near_noise`)."""
        return near_noise(self.local, self.points)

    def grid(self, node: int) -> LikelihoodGrid:
        """Node ``node``'s submap within ``coarse_range_m`` as a likelihood grid for the
        correlative search (the last few are kept: each holds a few megabytes)."""
        if node in self._grids:
            self._grids.move_to_end(node)
            return self._grids[node]
        p = self.params
        planar = self.get(node).points
        near = planar[np.hypot(planar[:, 0], planar[:, 1]) <= p.coarse_range_m]
        grid = LikelihoodGrid(
            near if len(near) else planar, p.coarse_resolution_m, p.coarse_sigma_m, 5,
            p.max_search_m,
        )  # fmt: skip
        self._grids[node] = grid
        if len(self._grids) > 8:
            self._grids.popitem(last=False)
        return grid

    def sample(self, node: int) -> FloatArray:
        """At most ``coarse_points`` of node ``node``'s submap points, spread over it."""
        planar = self.get(node, wide=False).points
        stride = max(1, len(planar) // self.params.coarse_points)
        return planar[::stride]

    def get(self, node: int, wide: bool = True) -> Sheet:
        """Node ``node``'s submap (node frame), ready to register; its ``points`` are the voxels'
        means, each once.

        ``wide``: the target's extent (``submap_m`` of travel either side; at the log's first or
        last scans all of its length on the one side there is), else the source's (``source_m``
        either side); scans closer than ``thin_m`` of travel to the last one taken are left
        out, so a slow or dense log costs what a sparse one does.
        """
        key = (node, wide)
        if key in self._cache:
            self._cache.move_to_end(key)
            return self._cache[key]
        p = self.params
        s = int(self.nodes[node])
        flat = self._gather(s, *self._span(node, wide))
        entry = sheet_of(flat, p.voxel_m if wide else p.source_voxel_m)
        self._cache[key] = entry
        self._cached_bytes += _sheet_bytes(entry)
        while self._cached_bytes > CACHED_SUBMAP_BYTES and len(self._cache) > 1:
            self._cached_bytes -= _sheet_bytes(self._cache.popitem(last=False)[1])
        return entry

    def scans(self, node: int, wide: bool = True) -> tuple[FloatArray, list[FloatArray]]:
        """The scans node ``node``'s submap is made of (:meth:`get`): their poses (K, 3) in the
        node's frame and their points (robot frame)."""
        s = int(self.nodes[node])
        taken = self._taken(s, *self._span(node, wide))
        ix, iy, ith = inverse(self.local[s, 0], self.local[s, 1], self.local[s, 2])
        ks = np.array(taken, dtype=np.intp)
        rx, ry, rth = compose(ix, iy, ith, self.local[ks, 0], self.local[ks, 1], self.local[ks, 2])
        return np.column_stack([rx, ry, rth]).reshape(-1, 3), [self.points[k] for k in taken]

    def _span(self, node: int, wide: bool) -> tuple[int, int]:
        """The scans (first, past the last) within a submap's extent of node ``node``."""
        p = self.params
        s = int(self.nodes[node])
        reach = p.submap_m if wide else p.source_m
        a, b = float(self.travel[s]) - reach, float(self.travel[s]) + reach
        if wide:
            # near the log's first or last scan a target keeps its length on the one side it
            # has: a robot brought back to where it started sees the start's surroundings, not
            # only what the first metres of the log saw of them (the source stays as it is: it
            # is what the robot saw on its way back)
            first, last = float(self.travel[0]), float(self.travel[-1])
            a = max(first, min(a, last - 2 * reach))
            b = min(last, a + 2 * reach)
        lo = int(np.searchsorted(self.travel, a, side="left"))
        hi = int(np.searchsorted(self.travel, b, side="right"))
        return lo, hi

    def _taken(self, s: int, lo: int, hi: int) -> list[int]:
        """Scan ``s`` and the scans ``lo`` to ``hi`` around it that a submap takes: a scan closer
        than ``thin_m`` of travel to the last one taken is left out, so a slow or dense log
        costs what a sparse one does; so are scans without a point."""
        taken = [s]
        last = -math.inf
        travel = self.travel
        for k in range(lo, hi):
            if k == s or len(self.points[k]) == 0 or abs(travel[k] - last) < self.params.thin_m:
                continue
            last = float(travel[k])
            taken.append(k)
        if len(self.points[s]) == 0:
            taken.pop(0)
        return taken

    def _gather(self, s: int, lo: int, hi: int) -> FloatArray:
        """The points (K, 2) of the scans :meth:`_taken` takes, in scan ``s``'s frame."""
        taken = self._taken(s, lo, hi)
        if not taken:
            return np.zeros((0, 2))
        ix, iy, ith = inverse(self.local[s, 0], self.local[s, 1], self.local[s, 2])
        ks = np.array(taken)
        rx, ry, rth = compose(ix, iy, ith, self.local[ks, 0], self.local[ks, 1], self.local[ks, 2])
        # each scan's turn as math.cos/sin of its own angle, the points moved in one go
        counts = [len(self.points[k]) for k in taken]
        cos = np.repeat([math.cos(t) for t in rth.tolist()], counts)
        sin = np.repeat([math.sin(t) for t in rth.tolist()], counts)
        pts = np.concatenate([self.points[k] for k in taken])
        x = np.repeat(rx, counts) + cos * pts[:, 0] - sin * pts[:, 1]
        y = np.repeat(ry, counts) + sin * pts[:, 0] + cos * pts[:, 1]
        return np.column_stack([x, y])


def _sheet_bytes(sheet: Sheet) -> int:
    """The memory a built submap holds: its arrays, or where small_gicp holds the sheet, its
    three copies of each point with their covariances (4 and 16 doubles each)."""
    if sheet.covs is not None:
        dims = 0 if sheet.dims is None else sheet.dims.nbytes
        return int(sheet.points.nbytes + dims + sheet.covs.nbytes)
    return int(sheet.points.nbytes + len(sheet) * 3 * 20 * 8)


def verify(
    i: int,
    j: int,
    guess: tuple[float, float, float],
    submaps: Submaps,
    radius_m: float,
    coarse: bool = True,
    partial: list[Closure] | None = None,
) -> Closure | None:
    """Register node ``i``'s submap onto node ``j``'s from ``guess`` (i in j's frame); the
    accepted closure (j's pose in i's frame; its ``j`` the keyframe the coarse search moved the
    target to, if it did) or None. ``coarse``: whether the correlative search may find a start
    where GICP from ``guess`` fails. ``partial``: where given, a candidate that passes every
    test but the gate is appended there (:func:`holds_where_seen` judges it later).
    A closure found further than ``coarse_from_m`` from its guess is refused where its source
    contradicts its target's view (:func:`contradicts_target`)."""
    p = submaps.params
    target, source = submaps.get(j), submaps.get(i, wide=False)
    if len(source.points) < 50 or len(target.points) < 50:
        return None
    best = _align(target, source, guess, p)
    poor = best is None or best[0] < p.min_inlier_fraction
    reach = radius_m
    if poor and coarse and radius_m > p.coarse_from_m:
        submaps.coarse_runs += 1
        # within the drift rule's radius first: a place that looks like this one (the same
        # doors further along) may lie within the whole window, and the drift rule says which
        # of them the robot is likelier at; only where nothing within it registers is the
        # estimate taken to have drifted further
        near = search(
            submaps.grid(j), submaps.sample(i), guess, radius_m, p.coarse_window_rad,
            p.coarse_step_rad, p.coarse_min_score,
        )  # fmt: skip
        if near is not None:
            best = _align(target, source, (near.x_m, near.y_m, near.theta_rad), p)
        found = None
        if best is None or best[0] < p.min_inlier_fraction:
            found = _coarse(submaps, i, j, guess)
        if found is not None:
            k, start = found
            if k != j:
                guess = _reframe(submaps, j, k, guess)
                j, target = k, submaps.get(k)
            reach = p.max_search_m
            best = _align(target, source, start, p)
    if best is None:
        return None
    in_part = best[0] < p.min_inlier_fraction
    if in_part and partial is None:
        return None
    fraction, pose, hessian = best
    if math.hypot(pose[0] - guess[0], pose[1] - guess[1]) > reach + p.correspondence_m:
        return None
    values = np.linalg.eigvalsh(hessian)
    if values[1] <= 0 or values[0] / values[1] < p.degenerate_ratio:
        return None
    px, py, pth = (np.asarray(v) for v in pose)
    rx, ry, rth = inverse(px, py, pth)
    closure = Closure(i, j, float(rx), float(ry), float(rth), fraction)
    if in_part:
        assert partial is not None
        partial.append(closure)
        return None
    # a place that looks like the true one passes the gate as well, and this far from the guess
    # the estimate no longer says which of them the robot is at: what the source puts in the
    # target's free space does
    far = math.hypot(pose[0] - guess[0], pose[1] - guess[1]) > p.coarse_from_m
    if far and contradicts_target(submaps, closure):
        return None
    return closure


def near_ends(ends: FloatArray, a: float, b: float, within_m: float) -> bool:
    """Whether some pair of path positions in ``ends`` (M, 2) lies within ``within_m`` of
    (``a``, ``b``) at both ends."""
    if len(ends) == 0:
        return False
    return bool(((np.abs(ends[:, 0] - a) < within_m) & (np.abs(ends[:, 1] - b) < within_m)).any())


def _placed(submaps: Submaps, closure: Closure) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """A closure's source submap placed by it in its target's frame, and which of its points
    lie within the inlier band of the target's submap."""
    x, y, th = inverse(
        np.asarray(closure.dx_m), np.asarray(closure.dy_m), np.asarray(closure.dtheta_rad)
    )
    moved = placed_points(
        submaps.get(closure.i, wide=False).points, (float(x), float(y), float(th))
    )
    return moved, np.isfinite(nearest_m(submaps.get(closure.j), moved, submaps.params.inlier_m))


def holds_where_seen(submaps: Submaps, closure: Closure) -> bool:
    """Whether a closure under the gate holds on its target's view (:mod:`.overlap`)."""
    p = submaps.params
    moved, inlier = _placed(submaps, closure)
    scans = submaps.scans(closure.j)
    return holds_in_part(moved, inlier, scans, submaps.noise, p.min_inlier_fraction, p.inlier_m)


def contradicts_target(submaps: Submaps, closure: Closure) -> bool:
    """Whether a closure's source submap, placed by it, contradicts its target's view beyond
    chance (:func:`.overlap.contradicts`)."""
    moved, inlier = _placed(submaps, closure)
    scans = submaps.scans(closure.j)
    return contradicts(moved, inlier, scans, submaps.noise, submaps.params.inlier_m)


def _coarse(
    submaps: Submaps, i: int, j: int, guess: tuple[float, float, float]
) -> tuple[int, tuple[float, float, float]] | None:
    """A start for GICP from the correlative search, and the keyframe to register against.

    The keyframe offered is the one nearest node ``i`` *in the estimate*; where the estimate
    has drifted, the keyframe of the first pass whose submap the source overlaps may lie metres
    along that pass, and the offered one saw only part of what the source saw. Its grid still
    places the source (scored over the whole window cap, the drift rule's radius being a guess
    at the drift, not a bound), but on it a true pose scores only the overlap. So the place
    found picks the target, the keyframe of the offered submap nearest it (:func:`_retarget`),
    and the gate is judged on that keyframe's own grid, a few cells and heading steps around
    the pose (the two grids round it differently): the same test a keyframe offered at the
    right place passes. None when that scores under ``coarse_min_score``.
    """
    p = submaps.params
    found = search(
        submaps.grid(j), submaps.sample(i), guess, p.max_search_m, p.coarse_window_rad,
        p.coarse_step_rad, 0.0,
    )  # fmt: skip
    if found is None:
        return None
    k, start = _retarget(submaps, i, j, found)
    again = search(
        submaps.grid(k), submaps.sample(i), start, 2 * p.coarse_resolution_m,
        2 * p.coarse_step_rad, p.coarse_step_rad, p.coarse_min_score,
    )  # fmt: skip
    if again is None:
        return None
    return k, (again.x_m, again.y_m, again.theta_rad)


def _retarget(
    submaps: Submaps, i: int, j: int, found: SearchResult
) -> tuple[int, tuple[float, float, float]]:
    """The keyframe nearest the pose found for node ``i`` on node ``j``'s grid, among those
    whose scans built that grid (within ``submap_m`` of travel of ``j``) and far enough back
    along the path from ``i``; and that pose in its frame."""
    p = submaps.params
    local = submaps.local[submaps.nodes]
    x, y, _ = compose(local[j, 0], local[j, 1], local[j, 2], found.x_m, found.y_m, found.theta_rad)
    span = np.abs(submaps.node_travel - submaps.node_travel[j]) <= p.submap_m
    span &= submaps.node_path[i] - submaps.node_path >= p.min_path_m
    span[i:] = False
    ks = np.flatnonzero(span)
    if len(ks) == 0:
        return j, (found.x_m, found.y_m, found.theta_rad)
    k = int(ks[np.argmin(np.hypot(local[ks, 0] - float(x), local[ks, 1] - float(y)))])
    return k, _reframe(submaps, j, k, (found.x_m, found.y_m, found.theta_rad))


def _reframe(
    submaps: Submaps, j: int, k: int, pose: tuple[float, float, float]
) -> tuple[float, float, float]:
    """``pose`` (in node ``j``'s frame) in node ``k``'s frame, through the scan-matched track."""
    local = submaps.local[submaps.nodes]
    x, y, th = compose(local[j, 0], local[j, 1], local[j, 2], *pose)
    ix, iy, ith = inverse(local[k, 0], local[k, 1], local[k, 2])
    rx, ry, rth = compose(ix, iy, ith, x, y, th)
    return float(rx), float(ry), float(wrap_angle(rth))


def _align(
    target: Sheet, source: Sheet, start: tuple[float, float, float], p: ClosureParams
) -> tuple[float, tuple[float, float, float], FloatArray] | None:
    result = align(target, source, start, p.correspondence_m, 30)
    pose = result.pose
    c, s = math.cos(pose[2]), math.sin(pose[2])
    xy = source.points
    moved = np.column_stack(
        [pose[0] + c * xy[:, 0] - s * xy[:, 1], pose[1] + s * xy[:, 0] + c * xy[:, 1]]
    )
    fraction = int(np.count_nonzero(np.isfinite(nearest_m(target, moved, p.inlier_m))))
    return fraction / len(xy), pose, result.hessian_xy


def relative(poses: FloatArray, i: int, j: int) -> tuple[float, float, float]:
    """Node ``i``'s pose in node ``j``'s frame."""
    ix, iy, ith = inverse(poses[j, 0], poses[j, 1], poses[j, 2])
    x, y, th = compose(ix, iy, ith, poses[i, 0], poses[i, 1], poses[i, 2])
    return float(x), float(y), float(wrap_angle(th))
