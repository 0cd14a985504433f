"""The SLAM benchmark of Kümmerle et al. 2009: a track scored against ground-truth relations.

A relations file holds one relation per line, ``t1 t2 x y z roll pitch yaw``: the robot's pose
at ``t2`` in its frame at ``t1`` (seconds on the log's own clock, metres, radians; z, roll and
pitch are zero for planar logs and ignored). The error of one relation is the estimated relative
pose composed with the inverse of the true one; its translation (m) and rotation (deg) are
averaged over all relations the track covers.

The pose at a relation's stamp is the track's pose nearest in time if within ``tolerance_s``
(0.1 s), else that nearest pose moved on by the odometry from its stamp to the relation's (what
the benchmark's own evaluator does). A relation with a stamp outside the track's time span is
left out and counted.

The relations name poses by the log's own stamps. Where the reader had to move stamps so that
time increases (a CARMEN log whose stamps go back by up to a second, on as many as a third of
its lines), the poses are looked up by the stamps their lines carried (:func:`on_logged_clock`);
by the moved ones, a relation end would take the pose of another line, up to a second away.

A log republished with times from its start and relations on the original clock differ by a
constant; :func:`find_clock_offset` finds it from the stamps alone. Most relation stamps are stamps
the log recorded (its scans'), so at the right offset most of them land on one of the log's stamps,
far more than chance would put there; at a wrong one about chance does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import numpy as np
import numpy.typing as npt
from scipy.stats import binom

from gridmap_cli.errors import InputFileError
from gridmap_cli.geometry import compose, inverse, wrap_angle
from gridmap_cli.poses.sync import interpolate_pose, stamp_groups
from gridmap_cli.records import MovedStamps, PoseTrack, RangeLog

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Relations:
    """Ground-truth relative poses, shape (R,) each: stamps (ns) and the pose at ``t2_ns`` in the
    frame at ``t1_ns`` (metres, radians)."""

    t1_ns: npt.NDArray[np.int64]
    t2_ns: npt.NDArray[np.int64]
    dx_m: FloatArray
    dy_m: FloatArray
    dtheta_rad: FloatArray

    def __len__(self) -> int:
        return int(self.t1_ns.shape[0])


@dataclass(frozen=True)
class RelationScore:
    """Mean and standard deviation of the translational (m) and rotational (deg) error over
    ``count`` relations; ``skipped`` relations had a stamp outside the track."""

    count: int
    skipped: int
    trans_mean_m: float
    trans_std_m: float
    rot_mean_deg: float
    rot_std_deg: float

    def summary(self) -> dict[str, float | int]:
        """For people and JSON (rounded)."""
        return {
            "relations": self.count,
            "skipped": self.skipped,
            "trans_mean_m": round(self.trans_mean_m, 4),
            "trans_std_m": round(self.trans_std_m, 4),
            "rot_mean_deg": round(self.rot_mean_deg, 3),
            "rot_std_deg": round(self.rot_std_deg, 3),
        }


def read_relations(source: Path | TextIO, name: str | None = None) -> Relations:
    """Read a relations file (a path or an open text handle; ``name`` for messages).

    Blank lines and ``#`` comments are skipped. Raises :class:`InputFileError` naming
    ``path:line`` for a line that is not eight numbers.
    """
    if isinstance(source, Path):
        with source.open(encoding="utf-8") as handle:
            return read_relations(handle, str(source))
    label: str = name or str(getattr(source, "name", "<relations>"))
    rows: list[tuple[int, int, float, float, float]] = []
    for number, text in enumerate(source, start=1):
        body = text.split("#", 1)[0].strip()
        if not body:
            continue
        fields = body.split()
        if len(fields) != 8:
            expected = "expected 8 fields 't1 t2 x y z roll pitch yaw'"
            raise InputFileError(label, f"{expected}, found {len(fields)}", number)
        try:
            values = [float(f) for f in fields]
        except ValueError:
            bad = next(f for f in fields if not _is_number(f))
            raise InputFileError(label, f"not a number: {bad!r}", number) from None
        if not all(math.isfinite(v) for v in values):
            raise InputFileError(label, "values must be finite", number)
        rows.append(
            (round(values[0] * 1e9), round(values[1] * 1e9), values[2], values[3], values[7])
        )
    if not rows:
        raise InputFileError(label, "holds no relation")
    t1, t2, dx, dy, dth = zip(*rows, strict=True)
    return Relations(
        t1_ns=np.array(t1, dtype=np.int64),
        t2_ns=np.array(t2, dtype=np.int64),
        dx_m=np.array(dx, dtype=np.float64),
        dy_m=np.array(dy, dtype=np.float64),
        dtheta_rad=np.array(dth, dtype=np.float64),
    )


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def poses_at(
    track: PoseTrack,
    stamp_ns: npt.NDArray[np.int64],
    odometry: PoseTrack | None = None,
    tolerance_s: float = 0.1,
) -> tuple[FloatArray, FloatArray, FloatArray, npt.NDArray[np.bool_]]:
    """The track's pose at each stamp, the benchmark's way: x, y, theta and a validity mask.

    The nearest pose within ``tolerance_s``; else the nearest pose carried by ``odometry``'s
    motion between its stamp and the wanted one (without ``odometry``: the track interpolated).
    A stamp outside the track's span (beyond the tolerance) is invalid.
    """
    t = track.stamp_ns
    tol_ns = round(tolerance_s * 1e9)
    hi = np.clip(np.searchsorted(t, stamp_ns), 1, max(len(t) - 1, 1))
    lo = hi - 1 if len(t) > 1 else hi * 0
    near = np.where(np.abs(t[hi] - stamp_ns) < np.abs(stamp_ns - t[lo]), hi, lo)
    gap = np.abs(t[near] - stamp_ns)
    valid = (stamp_ns >= t[0] - tol_ns) & (stamp_ns <= t[-1] + tol_ns)
    x, y, th = track.x_m[near].copy(), track.y_m[near].copy(), track.theta_rad[near].copy()
    far = gap > tol_ns
    if far.any():
        if odometry is not None:
            ax, ay, ath, ok_a = interpolate_pose(odometry, t[near[far]])
            bx, by, bth, ok_b = interpolate_pose(odometry, stamp_ns[far])
            ix, iy, ith = inverse(ax, ay, ath)
            mx, my, mth = compose(ix, iy, ith, bx, by, bth)
            fx, fy, fth = compose(x[far], y[far], th[far], mx, my, mth)
            valid[far] &= ok_a & ok_b
        else:
            fx, fy, fth, ok = interpolate_pose(track, stamp_ns[far])
            valid[far] &= ok
        x[far], y[far], th[far] = fx, fy, fth
    return x, y, th, valid


def on_logged_clock(track: PoseTrack, moved: MovedStamps) -> PoseTrack:
    """``track`` with each pose at a moved stamp put back at the stamp the log gave it, in the
    order of those stamps (stable), so the relations find the poses they name.

    Equal stamps are spread over the step they were printed to (:func:`printed_step_ns`), in
    their order: a log printed with six significant digits (a Unix time from 1,000 s on) gives
    up to ten lines the same stamp, a 10 ms step standing for the moments within it, and the
    relations' stamps, to the microsecond, fall among them.
    """
    return reordered_on_logged_clock(track, moved)[0]


def reordered_on_logged_clock(
    track: PoseTrack, moved: MovedStamps
) -> tuple[PoseTrack, npt.NDArray[np.intp]]:
    """:func:`on_logged_clock` and the order it took the poses of ``track`` in (indices into
    ``track``), for what is written beside each pose (status, covariance)."""
    if len(moved.stamp_ns) == 0:
        return track, np.arange(len(track))
    at = np.clip(np.searchsorted(moved.stamp_ns, track.stamp_ns), 0, len(moved.stamp_ns) - 1)
    hit = moved.stamp_ns[at] == track.stamp_ns
    stamps = np.where(hit, moved.logged_ns[at], track.stamp_ns)
    order = np.argsort(stamps, kind="stable")
    sorted_ns = stamps[order].astype(np.int64)
    first, group = stamp_groups(sorted_ns)
    size = np.bincount(group)[group]
    rank = np.arange(len(sorted_ns), dtype=np.int64) - first[group]
    step = printed_step_ns(sorted_ns)
    spread = np.where(size > 1, ((rank + 0.5) / size - 0.5) * step, 0.0)
    sorted_ns = sorted_ns + np.round(spread).astype(np.int64)
    # still strictly increasing where a spread meets the next stamp: one nanosecond apart
    index = np.arange(len(sorted_ns), dtype=np.int64)
    sorted_ns = np.maximum.accumulate(sorted_ns - index) + index
    return PoseTrack(
        stamp_ns=sorted_ns,
        x_m=track.x_m[order],
        y_m=track.y_m[order],
        theta_rad=track.theta_rad[order],
    ), order


def printed_step_ns(stamp_ns: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
    """The step each stamp (M,) was printed to, ns: for each decade of seconds, the largest power
    of ten from 1 us to 1 s that divides every stamp of that decade (a log printed with six
    significant digits: 1 ms from 100 s, 10 ms from 1,000 s; one printed to the microsecond:
    1 us)."""
    seconds = np.maximum(np.abs(stamp_ns) / 1e9, 1e-9)
    decade = np.floor(np.log10(seconds)).astype(np.int64)
    step = np.full(len(stamp_ns), 1_000, dtype=np.int64)
    for d in np.unique(decade):
        inside = decade == d
        q = 1_000_000_000
        while q > 1_000 and np.any(stamp_ns[inside] % q):
            q //= 10
        step[inside] = q
    return step


def moved_to(track: PoseTrack, x_m: float, y_m: float) -> PoseTrack:
    """``track`` with each pose moved to the point (``x_m``, ``y_m``) of its own frame, its
    heading kept: the track of that point of the robot (a laser's, say)."""
    x, y, _ = compose(
        track.x_m, track.y_m, track.theta_rad,
        np.full(len(track.x_m), x_m), np.full(len(track.x_m), y_m), np.zeros(len(track.x_m)),
    )  # fmt: skip
    return PoseTrack(stamp_ns=track.stamp_ns, x_m=x, y_m=y, theta_rad=track.theta_rad.copy())


def score_track(
    track: PoseTrack,
    relations: Relations,
    odometry: PoseTrack | None = None,
    tolerance_s: float = 0.1,
    offset_s: float = 0.0,
    moved: MovedStamps | None = None,
) -> RelationScore:
    """Score ``track`` (any frame) against ``relations``; see the module text.

    ``offset_s``: the relations' clock minus the track's (0 when both carry the log's own clock;
    a log republished with times from its start needs the start's time here). ``moved``: the
    stamps the reader moved (``RangeLog.moved_stamps``): the track and the odometry are looked up
    by the log's own stamps there.
    """
    if moved is not None:
        track = on_logged_clock(track, moved)
        odometry = None if odometry is None else on_logged_clock(odometry, moved)
    shift = round(offset_s * 1e9)
    x1, y1, t1, ok1 = poses_at(track, relations.t1_ns - shift, odometry, tolerance_s)
    x2, y2, t2, ok2 = poses_at(track, relations.t2_ns - shift, odometry, tolerance_s)
    ok = ok1 & ok2
    ix, iy, ith = inverse(x1[ok], y1[ok], t1[ok])
    ex, ey, eth = compose(ix, iy, ith, x2[ok], y2[ok], t2[ok])  # estimated relative pose
    gx, gy, gth = inverse(relations.dx_m[ok], relations.dy_m[ok], relations.dtheta_rad[ok])
    dx, dy, dth = compose(gx, gy, gth, ex, ey, eth)
    trans = np.hypot(dx, dy)
    rot = np.degrees(np.abs(wrap_angle(dth)))
    count = int(ok.sum())
    if count == 0:
        nan = float("nan")
        return RelationScore(0, len(relations), nan, nan, nan, nan)
    return RelationScore(
        count=count,
        skipped=len(relations) - count,
        trans_mean_m=float(trans.mean()),
        trans_std_m=float(trans.std()),
        rot_mean_deg=float(rot.mean()),
        rot_std_deg=float(rot.std()),
    )


#: Two stamps this close name the same moment: a log printed with six significant digits steps
#: by 10 ms from 1,000 s on.
SAME_MOMENT_S = 0.01
#: How unlikely by chance a landing count must be for an offset to be taken: far below one over
#: the number of offsets a search tries.
CHANCE_P = 1e-9
#: Relation stamps that seed the search (each proposes the offsets landing it on a log stamp) and
#: relation stamps each proposal is checked against, spread evenly over the relations.
SEEDS, CHECKS = 8, 64


@dataclass(frozen=True)
class ClockOffset:
    """What the stamps say of the relations' clock against the log's.

    ``offset_s``: the relations' clock minus the log's, None when no offset makes the stamps
    agree; ``searched``: whether the log's own clock failed first. ``landed`` of ``inside``
    distinct relation stamps within the log's span land within :data:`SAME_MOMENT_S` of one of
    its stamps at ``offset_s`` (or at the best offset tried), where chance lands ``chance``.
    """

    offset_s: float | None
    searched: bool
    landed: int
    inside: int
    stamps: int
    chance: float

    def message(self) -> str:
        """One line for people."""
        counts = (
            f"{self.landed:,} of {self.inside:,} relation stamps in the log's span land on its "
            f"stamps, chance would land {self.chance:,.0f}"
        )
        if self.offset_s is None:
            return (
                "no clock offset found makes the relation stamps land on the log's stamps (at "
                f"best {counts}): give --relations-offset"
            )
        if not self.searched:
            return f"the relations are on the log's own clock ({counts})"
        return (
            f"the relations' clock is the log's + {self.offset_s:.3f} s, found from the stamps "
            f"({counts})"
        )


def logged_stamps(log: RangeLog) -> npt.NDArray[np.int64]:
    """Every moment ``log`` recorded (poses and held range readings), sorted, on the clock its
    file printed (where the reader moved stamps): what relation stamps name."""
    parts = [log.poses.stamp_ns]
    if log.stream is None and len(log.readings):
        parts.append(np.unique(log.readings.stamp_ns))
    stamps = np.unique(np.concatenate(parts)).astype(np.int64)
    moved = log.moved_stamps
    if moved is not None and len(moved.stamp_ns):
        at = np.clip(np.searchsorted(moved.stamp_ns, stamps), 0, len(moved.stamp_ns) - 1)
        stamps = np.where(moved.stamp_ns[at] == stamps, moved.logged_ns[at], stamps)
        stamps = np.unique(stamps)
    return stamps


def _landing(
    stamps: npt.NDArray[np.int64], wanted: npt.NDArray[np.int64], tol_ns: int
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.int64]]:
    """Per wanted stamp: whether it lands within ``tol_ns`` of one of ``stamps`` (sorted), and
    its signed distance to the nearest."""
    hi = np.clip(np.searchsorted(stamps, wanted), 1, len(stamps) - 1)
    lo = hi - 1
    d_hi, d_lo = stamps[hi] - wanted, stamps[lo] - wanted
    nearest = np.where(np.abs(d_hi) < np.abs(d_lo), d_hi, d_lo)
    return np.abs(nearest) <= tol_ns, nearest


def _chance(stamps: npt.NDArray[np.int64], tol_ns: int) -> float:
    """The share of the span of ``stamps`` within ``tol_ns`` of one of them: the chance a
    moment taken at random lands."""
    span = float(stamps[-1] - stamps[0]) + 2 * tol_ns
    covered = float(np.minimum(np.diff(stamps), 2 * tol_ns).sum()) + 2 * tol_ns
    return min(1.0, covered / span)


def find_clock_offset(
    stamps_ns: npt.NDArray[np.int64], relations: Relations, tolerance_s: float = SAME_MOMENT_S
) -> ClockOffset:
    """The offset (relations' clock minus the log's) at which most relation stamps land on the
    log's stamps ``stamps_ns`` (sorted, at least two), far beyond chance: 0 when the log's own
    clock does, else the best one a search of the stamps finds, else None."""
    rel = np.unique(np.concatenate([relations.t1_ns, relations.t2_ns]))
    if len(stamps_ns) < 2:
        return ClockOffset(None, False, 0, 0, len(rel), 0.0)
    tol = max(1, round(tolerance_s * 1e9))
    q = _chance(stamps_ns, tol)

    def judge(offset_ns: int) -> tuple[bool, int, int]:
        wanted = rel - offset_ns
        inside = (wanted >= stamps_ns[0] - tol) & (wanted <= stamps_ns[-1] + tol)
        landed = int((_landing(stamps_ns, wanted[inside], tol)[0]).sum())
        n = int(inside.sum())
        unlikely = n > 0 and float(binom.sf(landed - 1, n, q)) < CHANCE_P
        return unlikely and 2 * landed >= n, landed, n

    def result(offset_ns: int | None, searched: bool, landed: int, n: int) -> ClockOffset:
        offset = None if offset_ns is None else offset_ns / 1e9
        return ClockOffset(offset, searched, landed, n, len(rel), n * q)

    ok, landed, n = judge(0)
    if ok:
        return result(0, False, landed, n)
    best = _search(stamps_ns, rel, tol)
    ok, landed, n = judge(best)
    return result(best if ok else None, True, landed, n)


def _search(stamps: npt.NDArray[np.int64], rel: npt.NDArray[np.int64], tol_ns: int) -> int:
    """The offset (ns) landing the most of a few relation stamps spread over ``rel``: each seed
    proposes every offset that lands it on a log stamp, the checks count each proposal, and the
    best is centred on the residuals of the relation stamps it lands."""
    seeds = rel[np.unique(np.linspace(0, len(rel) - 1, SEEDS).round().astype(np.intp))]
    checks = rel[np.unique(np.linspace(0, len(rel) - 1, CHECKS).round().astype(np.intp))]
    best, best_count = 0, -1
    for seed in seeds:
        proposals = seed - stamps
        count = np.zeros(len(proposals), dtype=np.int64)
        for check in checks:
            count += _landing(stamps, check - proposals, tol_ns)[0]
        k = int(np.argmax(count))
        if count[k] > best_count:
            best, best_count = int(proposals[k]), int(count[k])
    landed, nearest = _landing(stamps, rel - best, tol_ns)
    if landed.any():
        best -= int(np.median(nearest[landed]))
    return best
