"""A closure whose two submaps overlap only in part: judged on what the target saw.

The closure gate asks that ``min_inlier_fraction`` of the source submap's points land on the
target's (:mod:`.loop_closure`). A robot that comes back along a way the first pass saw only
part of (from the other direction, or out of a side corridor) brings a source whose other part
the target never saw: a true closure of such a pair ends under the gate, and its loop stays
open. Points the target could not have seen are evidence neither way; points in the space its
beams crossed are evidence against. So a candidate under the gate is judged again on the
target's view, each source point looked up in the target's scans by bearing, and holds when
both of these do:

- *the gate over what the target saw*: the inliers are ``min_inlier_fraction`` of the source's
  points that a target beam reaches (its bearing covered, the echo no nearer than the point less
  the inlier band), inliers included;
- *no contradiction*: of those points, the share deep inside a target scan's free space
  (:data:`.free_space.DEPTH_M` nearer than the echoes about its bearing) is within the level at
  which the free-space check finds a revisit contradicting, taken from the log's own near pairs
  (scans near in time on the scan-matched track) at that count.

Both levels are the closure gate's and the free-space check's own; nothing here is new. Less
overlap is still less evidence: the part of the source the target never saw is what would have
told two look-alike places apart, and judged this way in the ordinary search, closures 2.6 m
off along a corridor got through. So the graph asks this only of the candidates on a track
that fails its free-space check (:mod:`.slam`), and keeps what it closes only where the check
then finds fewer contradictions.

**A closure found far from its guess** (further than the coarse search's start,
``coarse_from_m``) says the estimate is that far off; a place that looks like the true one (the
same doors further along, a room like the first room) says so too, and passes the gate as well.
What tells them apart is what the source put in the space the target's beams crossed: a wrong
place puts about twice the level's share of the points the target saw in its free space, or
more; a true one mostly less than the level. So such a closure is refused when it contradicts
its target's view (:func:`contradicts`, through :func:`.loop_closure.contradicts_target`): the
free-space check's own test, a share past the level at that count by more than chance over that
many points would give, at :data:`.free_space.SIGNIFICANCE` (a level passed by a point or two
of a hundred is still the level, and the check's floor on it is a fixed share, whatever the
count).

**A scan on the scan matcher's local map** that overlaps it only in part (a long step into new
space) is judged the same way (:func:`seen_and_holding`, for :mod:`.local_map`), but before the
log's near pairs are known: the level is the free-space check's floor, the least it ever is.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.special import bdtrc

from gridmap_cli.poses.correction.free_space import (
    DEPTH_M,
    LEVEL_MIN,
    MIN_RANGE_M,
    SIGNIFICANCE,
    at_bearing,
    level_at,
    polar,
)

FloatArray = npt.NDArray[np.float64]
Mask = npt.NDArray[np.bool_]


def views(
    points: FloatArray, xyz: FloatArray, scans: list[FloatArray], band_m: float
) -> tuple[Mask, Mask]:
    """Which of ``points`` (Q, 2) the scans (poses ``xyz`` (S, 3) in the points' frame, ``scans``
    their echoes, robot frame) saw, and which lie in their free space, each looked up in every
    scan at its bearing as the free-space check looks an echo up
    (:func:`.free_space.at_bearing`): *seen* by a scan that covers the bearing with its farther
    echo of the two no nearer than the point less ``band_m``; in its *free space* when, no
    nearer than :data:`.free_space.MIN_RANGE_M`, it lies :data:`.free_space.DEPTH_M` nearer
    than the free range there."""
    table = polar(scans)
    # every point in every scan's frame: (S, Q)
    c, s = np.cos(xyz[:, 2])[:, None], np.sin(xyz[:, 2])[:, None]
    dx, dy = points[None, :, 0] - xyz[:, 0, None], points[None, :, 1] - xyz[:, 1, None]
    qx, qy = c * dx + s * dy, -s * dx + c * dy
    slot = np.repeat(np.arange(len(scans)), len(points))
    covered, free_m, echo_m = at_bearing(table, slot, qx.ravel(), qy.ravel())
    r = np.hypot(qx.ravel(), qy.ravel())
    seen: Mask = np.any((covered & (r <= echo_m + band_m)).reshape(qx.shape), axis=0)
    free: Mask = np.any(
        (covered & (r >= MIN_RANGE_M) & (r < free_m - DEPTH_M)).reshape(qx.shape), axis=0
    )
    return seen, free


def _judged(
    moved: FloatArray, inlier: Mask, target: tuple[FloatArray, list[FloatArray]], band_m: float
) -> tuple[int, int]:
    """How many of ``moved`` the target saw (the inliers included), and how many of those that
    are not inliers lie in its free space (:func:`views`)."""
    seen, free = views(moved, target[0], target[1], band_m)
    seen |= inlier
    return int(seen.sum()), int((free & ~inlier).sum())


def holds_in_part(
    moved: FloatArray,
    inlier: Mask,
    target: tuple[FloatArray, list[FloatArray]],
    noise: FloatArray,
    gate: float,
    band_m: float,
) -> bool:
    """Whether a candidate under the closure gate holds on the target's view (see the module).

    ``moved`` (Q, 2): the source submap's points placed in the target's frame, ``inlier`` (Q,)
    those within ``band_m`` of the target's; ``target``: the target submap's scans, poses (K, 3)
    in its node's frame and echoes; ``noise``: the log's near pairs
    (:func:`.free_space.near_noise`); ``gate``: the closure gate's inlier share."""
    count, free = _judged(moved, inlier, target, band_m)
    if count == 0 or int(inlier.sum()) < gate * count:
        return False
    return free <= level_at(noise, count) * count


def seen_and_holding(
    moved: FloatArray,
    inlier: Mask,
    target: tuple[FloatArray, list[FloatArray]],
    gate: float,
    band_m: float,
    min_seen: int,
) -> Mask | None:
    """Which of ``moved`` the target saw (inliers included), where they hold as
    :func:`holds_in_part` judges a closure, but before the log's noise is known: at least
    ``min_seen`` of them, and the free-space level at its floor, :data:`.free_space.LEVEL_MIN`,
    the least any log's level is (what holds here would pass the closures' test too); None
    where they do not hold."""
    seen, free = views(moved, target[0], target[1], band_m)
    seen |= inlier
    count = int(seen.sum())
    if count < min_seen or int(inlier.sum()) < gate * count:
        return None
    return seen if int((free & ~inlier).sum()) <= LEVEL_MIN * count else None


def contradicts(
    moved: FloatArray,
    inlier: Mask,
    target: tuple[FloatArray, list[FloatArray]],
    noise: FloatArray,
    band_m: float,
) -> bool:
    """Whether the points ``moved`` (as :func:`holds_in_part` takes them) that the target saw
    lie in its free space past the level at their count, beyond chance (see the module)."""
    count, free = _judged(moved, inlier, target, band_m)
    level = level_at(noise, count)  # inf where nothing was seen or the log has no near pairs
    if level >= 1.0:
        return False
    return bool(bdtrc(free - 1, count, level) < SIGNIFICANCE)
