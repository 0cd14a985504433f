"""Whether a track's revisits agree with its scans: free-space contradictions, no ground truth.

A laser echo says two things: there is a surface at the echo, and the space between the sensor
and the echo is free. Where a track puts the robot back at a place it saw before, the two
visits' scans must agree on both: the echoes of one fall on or behind the surfaces the other
saw, never in the free space its beams crossed. A loop closed wrongly, or missed (the second
pass drawn beside or across the first), puts one visit's walls across the other's corridors.

**A pair of scans.** Each echo of one scan, placed by the track, is looked up in the other
scan's beams at its bearing (from the other's robot origin): it *contradicts* when it lies more
than :data:`DEPTH_M` nearer than every echo of the other's beams within :data:`ANGLE_RAD` of
that bearing, deep inside the space they crossed. Bearings the other scan has no echo at are
not compared. The pair's share is that of the way (the first scan's echoes in the second's
free space, or back) that contradicts less: something that came or went between the visits (a
person, a door) contradicts one way only, since the other visit's echoes stand behind it; a
misplaced visit puts each scan's walls across the other's free space, both ways. So a pair is
judged only when both ways compared :data:`MIN_COMPARED` echoes: one way alone cannot tell the
two apart. Two visits facing apart overlap at the edges of their views only, where one way
often compares a handful of echoes; near pairs, facing alike, always compare both ways.

**The log's own noise is the yardstick.** Scans near in time (each node of the track with the
next two, a few decimetres and degrees apart, placed relative to each other by the scan
matcher or the odometry over that short step) show what a consistent track still leaves:
range noise, grazing beams, people walking by, glass. Their shares' 99th percentile is the
noise's tail. Scans far apart along the path (more than the loop-closure search's shortest
loop: no scan match related them) that the track puts within :data:`REVISIT_M` are its
*revisits*. On a consistent track a revisit is one more pair of overlapping scans: at most 1 %
of revisits would pass the noise's tail, and fewer pass twice it. A revisit *contradicts* when
its share passes twice the tail and :data:`LEVEL_MIN` (the level); the track *fails* when more
revisits contradict than 1 % of them would by chance, at a binomial significance of
:data:`SIGNIFICANCE`. A share taken over fewer echoes is noisier: two visits facing apart
compare two dozen echoes where near pairs compare eighty, and two of two dozen pass a level
that two of eighty do not. So the tail is taken at each revisit's own count: each near pair's
share as a random draw of that many of its echoes would give it (:func:`tail_at`). A loop
closed wrongly or missed makes every revisit along it contradict (a third to a half of their
echoes), a consistent track next to none.

Several tracks of one log are judged against one noise (:func:`judged_together`): the least
noisy of their near pairs, since each track's near pairs hold the sensor's noise plus that
track's own short-step error.

**A check that cannot judge** (:attr:`FreeSpaceCheck.blind`): where the scan matching failed
between scans near in time, the near pairs disagree as much as a misplaced visit does and the
level rises past anything a revisit would show; the check then passes every track, so it says
it cannot judge instead (:func:`verdict`).

**The wide look** (:func:`wide_check`): the same check with revisits up to :data:`WIDE_M`
apart and near pairs over as far (each node with the next four). A closure off by a corridor's
width (one door or pillar along) draws the second pass beside the first and never within a
metre of it; at two metres the passes meet. The graph does not act on it (its repairs and the
automatic choice judge the check above); a track that fails it is warned of. Numpy and scipy
only; no file I/O.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree
from scipy.special import bdtrc, gammaln

from gridmap_cli.records import PoseTrack

F64 = npt.NDArray[np.float64]
Ints = npt.NDArray[np.intp]

#: Nodes are taken along the track every this far or this much turned (as the pose graph's
#: keyframes are): consecutive nodes overlap almost wholly.
NODE_M = 0.5
NODE_RAD = math.radians(20.0)
#: Near pairs: each node with the next this many nodes.
NEAR_STEPS = 2
#: A revisit: two nodes this close on the track (the near pairs' own spacing, so both kinds of
#: pair see the place from as far apart) and farther apart along the path than
#: :data:`FAR_PATH_M` (the loop-closure search's shortest loop: no scan match related them).
REVISIT_M = 1.0
FAR_PATH_M = 8.0
#: The wide look's revisits and near pairs (:func:`wide_check`): a corridor's width.
WIDE_M = 2.0
#: How deep inside another scan's free space an echo must lie to contradict it: a wall's
#: thickness and what a good match leaves between two visits (the pose graph's closures are
#: held to 5 cm), so only a misplaced wall counts, not a blurred one.
DEPTH_M = 0.2
#: ... and how far off its bearing: the free range at a bearing is the least of the beams
#: within this angle, so a contradiction holds under any turn of the pose within twice the
#: pose graph's closure sigma (1 degree), and a wall seen grazing does not count.
ANGLE_RAD = math.radians(2.0)
#: Echoes nearer than this to the looking scan's origin are not compared (the robot's own body,
#: and bearings that a few centimetres of pose turn through many beams).
MIN_RANGE_M = 0.5
#: A pair is judged when each of its two ways compared at least this many echoes.
MIN_COMPARED = 20
#: A bearing is covered by a scan when its two neighbouring beams are within this many beam
#: spacings of it.
GAP_SPACINGS = 1.5
#: Pairs compared at most of each kind, spread evenly over the log: bounds the cost.
MAX_PAIRS = 2000
#: Echoes of a scan compared at most, evenly spread over its beams (every beam still carves
#: free space): a share needs a few dozen.
MAX_ECHOES = 90
#: The noise's tail: the near pairs' quantile a consistent revisit passes this rarely.
TAIL_QUANTILE = 0.99
#: A revisit contradicts beyond this many times the tail.
TAIL_FACTOR = 2.0
#: ... and beyond this share at least: fewer than one echo in twenty is a chair's legs or a
#: corner, never a wall across a corridor (a track checked in a world without noise).
LEVEL_MIN = 0.05
#: The chance that a consistent track fails anyway: one log in a thousand.
SIGNIFICANCE = 1e-3
#: A check whose level (at the median near pair's count) passes this cannot judge its track:
#: a misplaced visit puts a third to a half of its echoes in the other's free space, so with
#: the level over a half not even one would count. Scans near in time that disagree so much
#: were placed wrongly relative to each other (the scan matching failed between them), and
#: such a track is no yardstick of its own noise.
BLIND_LEVEL = 0.5


@dataclass(frozen=True)
class Polar:
    """The scans of some nodes by bearing: ``key`` (E,) node slot times 8 plus the bearing
    shifted into [0, 2 pi], sorted; ``range_m`` (E,) the free range there (:func:`_eroded`);
    ``spacing`` (N,) each scan's median beam spacing (rad); ``echo_m`` (E,) the echo's own
    range."""

    key: F64
    range_m: F64
    spacing: F64
    echo_m: F64


@dataclass(frozen=True)
class FreeSpaceCheck:
    """A track's revisits against the noise: ``shares`` (R,) the contradicting share of each
    revisit counted and ``compared`` (R,) the echoes it was taken over; ``near`` (P, 2) the
    track's near pairs, share and echoes compared; ``noise`` (Q, 2) the near pairs the track is
    judged against (its own unless :func:`judged_together` gave the log's)."""

    shares: F64
    compared: F64
    near: F64
    noise: F64

    @property
    def revisits(self) -> int:
        return len(self.shares)

    @property
    def near_tail(self) -> float:
        """The tail (:data:`TAIL_QUANTILE`) of the track's own near pairs' shares."""
        return float(np.quantile(self.near[:, 0], TAIL_QUANTILE)) if len(self.near) else math.nan

    @cached_property
    def levels(self) -> F64:
        """The share beyond which each revisit contradicts, at its own count of echoes."""
        if len(self.noise) == 0:
            return np.full(self.revisits, math.inf)
        return np.maximum(TAIL_FACTOR * tail_at(self.noise, self.compared), LEVEL_MIN)

    @cached_property
    def level(self) -> float:
        """The level of a revisit compared on as many echoes as the median near pair."""
        if len(self.noise) == 0:
            return math.nan
        median = np.array([float(np.median(self.noise[:, 1]))])
        return max(TAIL_FACTOR * float(tail_at(self.noise, median)[0]), LEVEL_MIN)

    @property
    def contradicting(self) -> int:
        return int((self.shares > self.levels).sum())

    @property
    def share(self) -> float:
        """The share of the revisits that contradict (NaN without a revisit)."""
        return self.contradicting / self.revisits if self.revisits else math.nan

    @property
    def fails(self) -> bool:
        """More revisits contradict than the noise's tail would make by chance."""
        if self.revisits == 0 or len(self.noise) == 0:
            return False
        chance = 1.0 - TAIL_QUANTILE
        # the binomial upper tail P(X >= contradicting) from scipy.special: scipy.stats gives
        # the same tail but is a large import that nothing else in a slam build needs
        return bool(bdtrc(self.contradicting - 1, self.revisits, chance) < SIGNIFICANCE)

    @property
    def blind(self) -> bool:
        """The near pairs disagree so much that no misplaced visit would count
        (:data:`BLIND_LEVEL`)."""
        return bool(self.level > BLIND_LEVEL)

    def blindness(self) -> str:
        """Why the check cannot judge its track, in one clause."""
        return (
            f"the free-space check cannot judge the track: scans near in time disagree (a "
            f"place seen twice would need over {100 * self.level:.0f} % of its echoes inside "
            "the free space the first visit saw to count), so the scan matching between them "
            "failed and a loop closed wrongly would pass unseen"
        )

    def reason(self) -> str:
        """What fails, in one clause."""
        return (
            f"{self.contradicting} of {self.revisits} places the robot came back to "
            f"contradict the first visit (over {100 * self.level:.0f} % of their echoes inside "
            "the free space it saw, beyond what 99 % of scans near in time show): a loop closed "
            "wrongly or missed"
        )

    def as_dict(self) -> dict[str, Any]:
        def r(v: float) -> float | None:
            return None if math.isnan(v) else round(v, 4)

        return {
            "revisits": self.revisits,
            "contradicting": self.contradicting,
            "contradicting_share": r(self.share),
            "level": r(self.level),
            "near_pairs": len(self.near),
            "fails": self.fails,
            "blind": self.blind,
        }


def tail_at(noise: F64, counts: F64) -> F64:
    """The tail (:data:`TAIL_QUANTILE`) of the near pairs ``noise`` (Q, 2: share, echoes
    compared) for shares taken over each of ``counts`` (R,) echoes: a pair compared on more
    echoes than that contributes the share a random draw of that many of its echoes gives
    (hypergeometric), one compared on as many or fewer its own share. The quantile of that
    mixture, a multiple of one over the count."""
    pairs = np.column_stack([np.rint(noise[:, 0] * noise[:, 1]), noise[:, 1]])
    kinds, weight = np.unique(pairs, axis=0, return_counts=True)
    bad, total = kinds[:, 0], kinds[:, 1]
    out = np.empty(len(counts))
    for n in np.unique(counts):
        k = np.arange(int(n) + 1, dtype=np.float64)[:, None]
        cdf = (bad / total * n <= k + 1e-9).astype(np.float64)
        drawn = total > n
        b, t = bad[drawn], total[drawn]
        # P(k of the n drawn contradict) = C(b, k) C(t - b, n - k) / C(t, n)
        log_pmf = _log_choose(b, k) + _log_choose(t - b, n - k) - _log_choose(t, n)
        cdf[:, drawn] = np.cumsum(np.exp(log_pmf), axis=0)
        mixture = cdf @ weight / weight.sum()
        out[counts == n] = int(np.argmax(mixture >= TAIL_QUANTILE - 1e-12)) / n
    return out


def _log_choose(n: F64, k: F64) -> F64:
    """log C(n, k), -inf where k is outside [0, n]."""
    with np.errstate(all="ignore"):
        value = gammaln(n + 1) - gammaln(k + 1) - gammaln(n - k + 1)
    out: F64 = np.where((k < 0) | (k > n), -np.inf, value)
    return out


def judged_together(checks: dict[str, FreeSpaceCheck]) -> dict[str, FreeSpaceCheck]:
    """The checks of several tracks of one log judged against one noise: the near pairs of the
    track whose tail is least."""
    tails = {name: c.near_tail for name, c in checks.items() if not math.isnan(c.near_tail)}
    if not tails:
        return checks
    noise = checks[min(tails, key=lambda name: tails[name])].near
    return {name: dataclasses.replace(c, noise=noise) for name, c in checks.items()}


def nodes(xyz: F64) -> Ints:
    """Indices of the track's poses (N, 3) taken as nodes: the first, then each that moved
    :data:`NODE_M` or turned :data:`NODE_RAD` from the last."""
    keep = [0]
    lx, ly, lt = xyz[0]
    for k in range(1, len(xyz)):
        x, y, t = xyz[k]
        if math.hypot(x - lx, y - ly) >= NODE_M or abs(math.remainder(t - lt, math.tau)) >= (
            NODE_RAD
        ):
            keep.append(k)
            lx, ly, lt = x, y, t
    return np.array(keep, dtype=np.intp)


def polar(points: list[F64]) -> Polar:
    """The scans ``points`` (each (K, 2), robot frame) by bearing from the robot's origin."""
    keys, ranges, spacing = [], [], np.full(len(points), np.nan)
    for slot, p in enumerate(points):
        if len(p) < 2:
            continue
        bearing = np.arctan2(p[:, 1], p[:, 0]) + math.pi
        order = np.argsort(bearing)
        keys.append(8.0 * slot + bearing[order])
        ranges.append(np.hypot(p[order, 0], p[order, 1]))
        spacing[slot] = float(np.median(np.diff(bearing[order])))
    if not keys:
        return Polar(np.zeros(0), np.zeros(0), spacing, np.zeros(0))
    key = np.concatenate(keys)
    echo = np.concatenate(ranges)
    return Polar(key, _eroded(key, echo, float(np.nanmin(spacing))), spacing, echo)


def _eroded(key: F64, range_m: F64, spacing: float) -> F64:
    """Each beam's range as the least over the beams of its scan within :data:`ANGLE_RAD` of
    it (``key`` sorted, scans 8 apart so never two at once)."""
    out = range_m.copy()
    reach = math.ceil(ANGLE_RAD / max(spacing, math.radians(0.1)))
    for o in range(1, min(reach, len(key) - 1) + 1):
        close = (key[o:] - key[:-o]) <= ANGLE_RAD
        np.minimum(out[:-o], np.where(close, range_m[o:], np.inf), out=out[:-o])
        np.minimum(out[o:], np.where(close, range_m[:-o], np.inf), out=out[o:])
    return out


def one_way(look: Ints, echo: Ints, xyz: F64, points: list[F64], table: Polar) -> F64:
    """Per pair (P, 2): the echoes of node slots ``echo`` compared with the free space of node
    slots ``look`` (each (P,)), and those that contradict it; ``xyz`` (N, 3) the nodes' poses."""
    counts = [len(points[e]) for e in echo.tolist()]
    pair = np.repeat(np.arange(len(look)), counts)
    if len(pair) == 0:
        return np.zeros((len(look), 2))
    p = np.concatenate([points[e] for e in echo.tolist()])
    # the echoing scan's pose in the looking scan's frame, per pair, then each echo
    a, b = xyz[look], xyz[echo]
    ca, sa = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    tx, ty, turn = ca * dx + sa * dy, -sa * dx + ca * dy, b[:, 2] - a[:, 2]
    c, s = np.cos(turn)[pair], np.sin(turn)[pair]
    qx = tx[pair] + c * p[:, 0] - s * p[:, 1]
    qy = ty[pair] + s * p[:, 0] + c * p[:, 1]
    r = np.hypot(qx, qy)
    bearing, free, _ = at_bearing(table, look[pair], qx, qy)
    covered = bearing & (r >= MIN_RANGE_M)
    inside = covered & (r < free - DEPTH_M)
    return np.column_stack(
        [
            np.bincount(pair, weights=covered, minlength=len(look)),
            np.bincount(pair, weights=inside, minlength=len(look)),
        ]
    )


def at_bearing(
    table: Polar, slot: Ints, qx: F64, qy: F64
) -> tuple[npt.NDArray[np.bool_], F64, F64]:
    """Points (qx, qy), each in the frame of its scan ``slot`` of ``table``, looked up at their
    bearing: whether the scan's beams on both sides lie within :data:`GAP_SPACINGS` of its
    spacing (covered), the lesser free range of the two and the farther echo of the two."""
    key = 8.0 * slot + np.arctan2(qy, qx) + math.pi
    hi = np.searchsorted(table.key, key)
    lo = hi - 1
    n = len(table.key)
    hi_c, lo_c = np.minimum(hi, n - 1), np.maximum(lo, 0)
    gap = GAP_SPACINGS * table.spacing[slot]
    covered = (
        (hi < n)
        & (lo >= 0)
        & (np.floor(table.key[hi_c] / 8.0) == slot)
        & (np.floor(table.key[lo_c] / 8.0) == slot)
        & (table.key[hi_c] - key <= gap)
        & (key - table.key[lo_c] <= gap)
    )
    free = np.minimum(table.range_m[hi_c], table.range_m[lo_c])
    echo = np.maximum(table.echo_m[hi_c], table.echo_m[lo_c])
    return covered, free, echo


def pair_shares(pairs: Ints, xyz: F64, points: list[F64], table: Polar) -> F64:
    """The node-slot ``pairs`` (P, 2) whose two ways both compared :data:`MIN_COMPARED` echoes,
    each as its contradicting share and the echoes it was taken over (K, 2): the way with the
    lesser share (see the module)."""
    if len(pairs) == 0:
        return np.zeros((0, 2))
    one = one_way(pairs[:, 0], pairs[:, 1], xyz, points, table)
    back = one_way(pairs[:, 1], pairs[:, 0], xyz, points, table)
    ways = np.column_stack([one[:, 1] / np.maximum(one[:, 0], 1), back[:, 1] / np.maximum(
        back[:, 0], 1)])  # fmt: skip
    counts = np.column_stack([one[:, 0], back[:, 0]])
    # one way alone cannot tell a misplaced visit from something that came or went
    both = (counts >= MIN_COMPARED).all(axis=1)
    way = ways[both].argmin(axis=1)
    rows = np.arange(int(both.sum()))
    out: F64 = np.column_stack([ways[both][rows, way], counts[both][rows, way]])
    return out


def near_pairs(count: int, steps: int = NEAR_STEPS) -> Ints:
    """Each node slot with the next ``steps`` (P, 2)."""
    rows = [
        np.column_stack([np.arange(count - s), np.arange(s, count)])
        for s in range(1, steps + 1)
        if s < count
    ]
    return np.concatenate(rows).astype(np.intp) if rows else np.zeros((0, 2), dtype=np.intp)


def revisit_pairs(xyz: F64, radius_m: float = REVISIT_M) -> Ints:
    """Node slots within ``radius_m`` of each other on the track (``xyz`` (N, 3)) and more
    than :data:`FAR_PATH_M` apart along it (P, 2), in order."""
    if len(xyz) < 2:
        return np.zeros((0, 2), dtype=np.intp)
    steps = np.hypot(np.diff(xyz[:, 0]), np.diff(xyz[:, 1]))
    path = np.concatenate([[0.0], np.cumsum(steps)])
    found = cKDTree(xyz[:, :2]).query_pairs(radius_m, output_type="ndarray")
    if len(found) == 0:
        return np.zeros((0, 2), dtype=np.intp)
    found = np.sort(found, axis=1)
    kept = found[path[found[:, 1]] - path[found[:, 0]] > FAR_PATH_M]
    ordered: Ints = kept[np.lexsort((kept[:, 1], kept[:, 0]))].astype(np.intp)
    return ordered


def _thinned(points: F64) -> F64:
    """At most :data:`MAX_ECHOES` of a scan's echoes, every n-th."""
    step = -(-len(points) // MAX_ECHOES)
    return points[::step] if step > 1 else points


def _spread(pairs: Ints, limit: int) -> Ints:
    """At most ``limit`` of ``pairs``, evenly spread over them."""
    if len(pairs) <= limit:
        return pairs
    return pairs[np.linspace(0, len(pairs) - 1, limit).round().astype(np.intp)]


def check_track(xyz: F64, points: list[F64], radius_m: float = REVISIT_M) -> FreeSpaceCheck:
    """The free-space check of the poses ``xyz`` (S, 3) of the scans ``points`` (S arrays (K, 2),
    robot frame, echoes only), against the track's own near pairs; revisits within ``radius_m``
    and near pairs over as far (:data:`NEAR_STEPS` per :data:`REVISIT_M`), so that both kinds
    of pair see a place from as far apart."""
    if len(xyz) == 0:
        return FreeSpaceCheck(np.zeros(0), np.zeros(0), np.zeros((0, 2)), np.zeros((0, 2)))
    node_xyz, echoes, table = _node_scans(xyz, points)
    steps = round(NEAR_STEPS * radius_m / REVISIT_M)
    near = pair_shares(
        _spread(near_pairs(len(node_xyz), steps), MAX_PAIRS), node_xyz, echoes, table
    )
    far = pair_shares(
        _spread(revisit_pairs(node_xyz, radius_m), MAX_PAIRS), node_xyz, echoes, table
    )
    return FreeSpaceCheck(far[:, 0], far[:, 1], near, near)


def near_noise(xyz: F64, points: list[F64]) -> F64:
    """The near pairs of the track ``xyz`` (S, 3) of the scans ``points`` (:func:`check_track`'s
    ``near``, without its revisits): what the log's own noise leaves, (P, 2) share and echoes."""
    if len(xyz) == 0:
        return np.zeros((0, 2))
    node_xyz, echoes, table = _node_scans(xyz, points)
    return pair_shares(_spread(near_pairs(len(node_xyz)), MAX_PAIRS), node_xyz, echoes, table)


def _node_scans(xyz: F64, points: list[F64]) -> tuple[F64, list[F64], Polar]:
    """The track's nodes (:func:`nodes`): their poses, their echoes compared (thinned) and their
    scans by bearing."""
    at = nodes(xyz)
    table = polar([points[k] for k in at.tolist()])
    return xyz[at], [_thinned(points[k]) for k in at.tolist()], table


def level_at(noise: F64, count: int) -> float:
    """The share of ``count`` echoes beyond which they contradict a scan's free space, as a
    revisit compared on that many does (:attr:`FreeSpaceCheck.levels`), against the near pairs
    ``noise``; inf without them."""
    if len(noise) == 0 or count <= 0:
        return math.inf
    return max(TAIL_FACTOR * float(tail_at(noise, np.array([float(count)]))[0]), LEVEL_MIN)


def check_poses(track: PoseTrack, points: list[F64], radius_m: float = REVISIT_M) -> FreeSpaceCheck:
    """:func:`check_track` of ``track``, one pose per scan of ``points``."""
    if len(track.x_m) != len(points):
        raise ValueError(f"{len(track.x_m)} poses for {len(points)} scans")
    xyz = np.column_stack([track.x_m, track.y_m, track.theta_rad])
    return check_track(xyz, points, radius_m)


def wide_check(track: PoseTrack, points: list[F64]) -> FreeSpaceCheck:
    """The wide look (see the module): :func:`check_poses` with revisits within
    :data:`WIDE_M`."""
    return check_poses(track, points, WIDE_M)


def verdict(
    track: PoseTrack, points: list[F64], check: FreeSpaceCheck | None = None
) -> tuple[FreeSpaceCheck, FreeSpaceCheck | None, str | None]:
    """What a slam track is judged by and warned of: its check (``check`` where the graph
    already took it), the wide look where that passes (None where it fails: the track is warned
    of already), and the one-clause warning either gives, or that the check cannot judge the
    track (None when both pass and the check can judge)."""
    check = check if check is not None else check_poses(track, points)
    if check.fails:
        return check, None, check.reason()
    wide = wide_check(track, points)
    if wide.fails:
        where = f"where its passes come within {WIDE_M:g} m of each other"
        return check, wide, f"{where}, {wide.reason()}"
    return check, wide, check.blindness() if check.blind else None
