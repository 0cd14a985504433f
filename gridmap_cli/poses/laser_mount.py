"""Where the laser sits on the frame the odometry moves: its mounting measured from the log.

A laser's mounting (TF, a robot file, a CARMEN ``PARAM``) is typed in by hand and often wrong:
a laser bolted a few centimetres from where the URDF puts it, or logged at the robot's centre
when it sits ahead of it. The log itself says where it is. The scan matcher gives the laser's
motion; the odometry gives the motion of the frame it reports (base_link). When the robot turns
through an angle ``phi``, a laser ``m`` from that frame's origin moves by ``(R(phi) - I) m``
beyond what the base moved: over many turns that lever is measured, as in the simultaneous
calibration of odometry and sensor pose of Censi et al. (IEEE T-RO 2013).

The model, for pairs of scans a metre of travel apart (turning counted at a metre per radian):
the laser's step ``t_L`` (from the laser-based track with the mounting it was computed with put
back) against the odometry's step ``(t_O, R_O)``::

    t_L = A t_O + (R_O - I) m,    A = s R(delta)

``A`` absorbs the odometry's distance scale and any steady bias of its direction of travel, so
neither leaks into ``m``; ``m`` is the laser's position on the odometry's frame (up to the small
turn of a laser's yaw error, which it does not measure). Linear least squares, the worst pairs
trimmed; its spread by leaving out a tenth of the log at a time.

No file I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import given
from gridmap_cli.geometry import compose, inverse, wrap_angle
from gridmap_cli.poses.sync import laser_point
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import RobotDescription

if TYPE_CHECKING:
    from gridmap_cli.poses.correction.scan_match import ScanMatch

FloatArray = npt.NDArray[np.float64]

#: Travel between the two scans of a pair, turning counted at a metre per radian: a pair then
#: holds a turn of up to a radian or a metre of driving, long against the scan match's noise.
PAIR_M = 1.0
#: Pairs whose residual is over this many times the median are left out (a scan the matcher
#: placed badly, odometry that jumped), three times over.
TRIM = 3.0
#: Stretches of the log the spread is taken over (a delete-a-group jackknife): neighbouring
#: pairs share most of their scans, so they are left out together.
GROUPS = 10
#: Pairs that turned at least this much are the ones that measure the lever: fewer than
#: :data:`MIN_TURNS` of them and the mounting is not measured.
TURN_RAD = math.radians(20.0)
MIN_TURNS = 20
#: A mounting this close to the measured one is not worth a word: the lever it leaves moves a
#: reading at most twice this in a half turn, one 5 cm cell of the map.
TOLERANCE_M = 0.025
#: ... and it must lie this many spreads away: a measurement that cannot tell them apart is
#: no reason to doubt the mounting.
FIRM = 3.0


@dataclass(frozen=True)
class MountCheck:
    """The laser's position measured on the odometry's frame, against the mounting given.

    ``x_m``, ``y_m``: measured (metres, the base frame: x forward, y left); ``spread_m``: about
    95 % of its uncertainty, twice the jackknife's standard error over :data:`GROUPS`
    stretches of the log; ``given``: the mounting's (x, y); ``pairs``: pairs kept, ``turns`` of
    them turned :data:`TURN_RAD` or more; ``distance_scale``: the odometry's distance over the
    laser's (1: none to take out).
    """

    x_m: float
    y_m: float
    spread_m: float
    given: tuple[float, float]
    pairs: int
    turns: int
    distance_scale: float

    @property
    def off_m(self) -> float:
        """How far the given mounting is from the measured one (metres)."""
        return math.hypot(self.x_m - self.given[0], self.y_m - self.given[1])

    @property
    def disagrees(self) -> bool:
        """The mounting given is off by more than :data:`TOLERANCE_M` and by more than
        :data:`FIRM` spreads."""
        return self.off_m > TOLERANCE_M and self.off_m > FIRM * self.spread_m

    def as_dict(self) -> dict[str, object]:
        return {
            "x_m": round(self.x_m, 4),
            "y_m": round(self.y_m, 4),
            "spread_m": round(self.spread_m, 4),
            "given_x_m": round(self.given[0], 4),
            "given_y_m": round(self.given[1], 4),
            "off_m": round(self.off_m, 4),
            "disagrees": self.disagrees,
            "pairs": self.pairs,
            "turns": self.turns,
            "odometry_distance_scale": round(self.distance_scale, 4),
        }

    def reason(self) -> str:
        """One line for a warning: where the laser is measured, where it was said to be."""
        return (
            f"the odometry's turns put the laser at x {self.x_m:.3f} m, y {self.y_m:.3f} m on "
            f"the base frame (within {self.spread_m:.3f} m), {self.off_m:.3f} m from its "
            f"mounting (x {self.given[0]:.3f} m, y {self.given[1]:.3f} m): check the laser's "
            "mounting where the log takes it from (`gridmap inspect` says: a robot file, the "
            f"log's own, or a ROS recording's TF, which {given('laser_mount')} overrides); a "
            f"map from the odometry alone smears its walls by up to {2 * self.off_m:.2f} m "
            "where the robot turns"
        )


def check_match(
    log: RangeLog, robot: RobotDescription | None, match: ScanMatch
) -> MountCheck | None:
    """:func:`check_mount` of a scan match of ``log`` (its track against its odometry), with
    the mounting ``log`` and ``robot`` give its laser; None for lasers at more than one point
    or a log that does not measure it."""
    mount = laser_point(log, robot)
    return None if mount is None else check_mount(match.track, match.odometry, mount)


def check_mount(
    laser_track: PoseTrack, odometry: PoseTrack, mount: tuple[float, float]
) -> MountCheck | None:
    """The laser's position measured from ``laser_track`` (the base frame's poses that the scan
    matcher found with the laser at ``mount``, (x, y) metres) against ``odometry``, both at the
    same stamps (shape (S,)). None when the log does not measure it: fewer than
    :data:`MIN_TURNS` pairs that turned."""
    n = len(laser_track.stamp_ns)
    if n < 2 or len(odometry.stamp_ns) != n:
        return None
    # the laser's own positions, with the base's heading
    lx, ly, lth = compose(
        laser_track.x_m, laser_track.y_m, laser_track.theta_rad, mount[0], mount[1], 0.0
    )
    ox, oy, oth = odometry.x_m, odometry.y_m, odometry.theta_rad
    i, j = _pairs(ox, oy, oth)
    if len(i) == 0:
        return None
    tx, ty, _ = compose(*inverse(lx[i], ly[i], lth[i]), lx[j], ly[j], lth[j])
    ux, uy, turn = compose(*inverse(ox[i], oy[i], oth[i]), ox[j], oy[j], oth[j])
    c, s = np.cos(turn), np.sin(turn)
    # unknowns (a, b, mx, my): A = [[a, -b], [b, a]]
    rows = np.empty((2 * len(i), 4))
    rows[0::2] = np.column_stack([ux, -uy, c - 1.0, -s])
    rows[1::2] = np.column_stack([uy, ux, s, c - 1.0])
    rhs = np.empty(2 * len(i))
    rhs[0::2], rhs[1::2] = tx, ty
    kept = np.ones(len(i), dtype=bool)
    solution = _solve(rows, rhs, kept)
    for _ in range(3):
        residual = rows @ solution - rhs
        size = np.hypot(residual[0::2], residual[1::2])
        kept = size <= TRIM * float(np.median(size[kept]))
        solution = _solve(rows, rhs, kept)
    turned = kept & (np.abs(wrap_angle(turn)) >= TURN_RAD)
    if int(turned.sum()) < MIN_TURNS:
        return None
    # the jackknife's variance over stretches of the log, each left out in turn
    group = np.minimum(np.arange(len(i)) * GROUPS // len(i), GROUPS - 1)
    left_out = np.array([_solve(rows, rhs, kept & (group != g))[2:] for g in range(GROUPS)])
    variance = (GROUPS - 1) / GROUPS * ((left_out - left_out.mean(axis=0)) ** 2).sum(axis=0)
    spread = 2.0 * math.sqrt(float(variance.sum()))
    return MountCheck(
        x_m=float(solution[2]),
        y_m=float(solution[3]),
        spread_m=spread,
        given=(float(mount[0]), float(mount[1])),
        pairs=int(kept.sum()),
        turns=int(turned.sum()),
        distance_scale=1.0 / max(math.hypot(solution[0], solution[1]), 1e-9),
    )


def _pairs(
    x: FloatArray, y: FloatArray, theta: FloatArray
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """Each pose with the first pose :data:`PAIR_M` of travel after it (turning counted at a
    metre per radian), by the odometry; poses with no such later pose are left out."""
    steps = np.hypot(np.diff(x), np.diff(y)) + np.abs(wrap_angle(np.diff(theta)))
    travel = np.concatenate([[0.0], np.cumsum(steps)])
    j = np.searchsorted(travel, travel + PAIR_M, side="left")
    i = np.flatnonzero(j < len(travel))
    return i, j[i]


def _solve(rows: FloatArray, rhs: FloatArray, weight: npt.NDArray[np.generic]) -> FloatArray:
    """Least squares of ``rows`` (2P, 4) against ``rhs`` (2P,), pair p counted ``weight[p]``
    times (a mask, or counts of a draw)."""
    w = np.sqrt(np.repeat(np.asarray(weight, dtype=np.float64), 2))
    solution, *_ = np.linalg.lstsq(rows * w[:, None], rhs * w, rcond=None)
    return np.asarray(solution, dtype=np.float64)
