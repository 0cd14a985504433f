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
time increases (a CARMEN log whose stamps go back by up to a second: Intel, a third of its
lines), the poses are looked up by the stamps their lines carried (:func:`on_logged_clock`);
by the moved ones, a relation end would take the pose of another line, up to a second away.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import InputFileError
from gridmap_cli.geometry import compose, inverse, wrap_angle
from gridmap_cli.poses.sync import interpolate_pose, stamp_groups
from gridmap_cli.records import MovedStamps, PoseTrack

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
    their order: a log printed with six significant digits (the Intel log from 1,000 s on) gives
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
