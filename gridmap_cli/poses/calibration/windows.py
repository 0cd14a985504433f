"""Windows of travel: the odometry's motion against a reference's, window by window.

A window ends as soon as the reference has driven ``window_m`` metres or turned ``window_rad``
radians since it began. Over each window the two motions are compared through what no frame
changes (the length of the window's displacement, the sum of its turns), so the error a window
shows is the error made within it, whatever the drift before it: :mod:`.calibrate` fits them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.poses.calibration.robust_fit import Rung
from gridmap_cli.poses.odometry_error import travelled
from gridmap_cli.poses.sync import interpolate_pose
from gridmap_cli.poses.uncertainty.pose_uncertainty import key_steps
from gridmap_cli.records import PoseTrack, RangeLog, stamps_advance

FloatArray = npt.NDArray[np.float64]

DEFAULT_WINDOW_M = 1.0
DEFAULT_WINDOW_RAD = math.pi / 2
#: A window's budget counts as used up within this much (metres or radians) of it.
BUDGET_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Windows:
    """Per-window comparison of odometry and truth, shape (W,) each, and the windows' budgets.

    ``driven_m``, ``turned_rad``: true path length and signed true rotation in the window;
    ``displacement_m``: length of the true relative translation; ``distance_error_m`` and
    ``heading_error_rad``: odometry minus truth (see module docstring). ``window_m`` and
    ``window_rad``: the distance and turn that close a window. ``start_s``, ``start_m``: where
    each window begins, seconds from the first pose and metres the reference had driven.
    """

    driven_m: FloatArray
    turned_rad: FloatArray
    displacement_m: FloatArray
    distance_error_m: FloatArray
    heading_error_rad: FloatArray
    window_m: float
    window_rad: float
    start_s: FloatArray
    start_m: FloatArray
    #: The turning the random walk grows with: the sum of the absolute net turns of the key
    #: steps (``window_m`` or ``window_rad`` each, as build's pose uncertainty cuts them) in
    #: the window, radians >= 0. A 10 m window that turns left and then right nets nothing,
    #: and the build still adds both turns' noise.
    key_turned_rad: FloatArray | None = None
    #: The reference's turn rate at each window's end less that at its start (rad/s): what a
    #: stamp offset of the odometry turns into heading error.
    turn_rate_change: FloatArray | None = None
    #: Where each window begins and ends in travel, counted in key steps' worth (metres over
    #: the key step's, plus absolute radians turned over its turn): a log that turns on the
    #: spot travels too.
    start_travel: FloatArray | None = None
    end_travel: FloatArray | None = None

    def __len__(self) -> int:
        return int(self.driven_m.shape[0])

    def rung(self) -> Rung:
        return Rung(
            driven_m=self.driven_m,
            turned_rad=self.turned_rad,
            displacement_m=self.displacement_m,
            distance_error_m=self.distance_error_m,
            heading_error_rad=self.heading_error_rad,
            start_s=self.start_s,
            start_m=self.start_m,
            window_m=self.window_m,
            key_turned_rad=np.abs(self.turned_rad)
            if self.key_turned_rad is None
            else self.key_turned_rad,
            turn_rate_change=np.zeros(len(self))
            if self.turn_rate_change is None
            else self.turn_rate_change,
            start_travel=self.start_m if self.start_travel is None else self.start_travel,
            end_travel=self.start_m + self.driven_m if self.end_travel is None else self.end_travel,
        )


def truth_at_odometry(log: RangeLog) -> tuple[PoseTrack, PoseTrack]:
    """Odometry and truth at the same stamps (the odometry's, within the truth's span).

    Raises :class:`~gridmap_cli.errors.InputFileError` for a log without ground truth.
    """
    odo, truth = log.poses, log.require_truth("calibrate compares the odometry against it")
    if np.array_equal(odo.stamp_ns, truth.stamp_ns):
        return odo, truth
    x, y, th, valid = interpolate_pose(truth, odo.stamp_ns)
    keep = valid
    return (
        PoseTrack(odo.stamp_ns[keep], odo.x_m[keep], odo.y_m[keep], odo.theta_rad[keep]),
        PoseTrack(odo.stamp_ns[keep], x[keep], y[keep], th[keep]),
    )


def key_turning(
    truth: PoseTrack, signed_turn: FloatArray, key_m: float, key_rad: float
) -> FloatArray:
    """At each pose (N,), the sum so far of the absolute net turns of the key steps of
    ``key_m`` or ``key_rad`` (:func:`~gridmap_cli.poses.uncertainty.pose_uncertainty.key_steps`),
    linear in the pose index within a key step; ``signed_turn``: the running sum of the wrapped
    turns."""
    if len(truth) == 0:
        return np.zeros(0)
    keys = key_steps(truth, key_m, key_rad)
    at_keys = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(signed_turn[keys])))])
    return np.asarray(np.interp(np.arange(len(truth)), keys, at_keys), dtype=np.float64)


def turn_rate(truth: PoseTrack, signed_turn: FloatArray) -> FloatArray:
    """The reference's turn rate at each pose (N,), rad/s: central differences in time. Stamps
    that do not advance (:func:`~gridmap_cli.records.stamps_advance`: a log that prints one time
    for every record) measure no time, so they give no rate, and the fit no stamp lag: a lag
    fitted on them would take a share of the heading error with it."""
    n = len(truth)
    if n < 2 or not stamps_advance(int(truth.stamp_ns[0]), int(truth.stamp_ns[-1]), n):
        return np.zeros(n)
    t = (truth.stamp_ns - truth.stamp_ns[0]).astype(np.float64) / 1e9
    if np.any(np.diff(t) <= 0.0):
        return np.zeros(n)
    return np.asarray(np.gradient(signed_turn, t), dtype=np.float64)


def compare_windows(
    odometry: PoseTrack,
    truth: PoseTrack,
    window_m: float = DEFAULT_WINDOW_M,
    window_rad: float = DEFAULT_WINDOW_RAD,
    key_m: float | None = None,
    key_rad: float | None = None,
    begin_at: npt.NDArray[np.int64] | None = None,
) -> Windows:
    """Cut the tracks (same stamps, shape (N,)) into windows of travel and compare them.

    Only complete windows are returned: the travel left over at the end is dropped. ``key_m``,
    ``key_rad``: the key steps whose absolute turns ``key_turned_rad`` sums (default: the
    window's own budgets). ``begin_at``: pose indices (sorted) where windows begin, each
    running until its budget is used up, so that they may overlap (default: one after another).
    """
    key_m = window_m if key_m is None else key_m
    key_rad = window_rad if key_rad is None else key_rad
    if not (window_m > 0.0 and math.isfinite(window_m)):
        raise ValueError(f"window must be a positive number of metres, got {window_m}")
    if not (window_rad > 0.0 and math.isfinite(window_rad)):
        raise ValueError(f"window turn must be a positive number of radians, got {window_rad}")
    dist, rot = travelled(truth)
    # the heading error needs the signed rotation, which travelled() does not keep
    signed_true = np.concatenate([[0.0], np.cumsum(wrap_angle(np.diff(truth.theta_rad)))])
    signed_odo = np.concatenate([[0.0], np.cumsum(wrap_angle(np.diff(odometry.theta_rad)))])
    starts: list[int] = []
    ends: list[int] = []
    i = 0
    n = dist.shape[0]
    pending = None if begin_at is None else [int(b) for b in begin_at]
    while i < n - 1:
        # first pose at which either budget is used up, to within rounding: a 90-degree corner
        # must close a 90-degree window whether its increments sum to pi/2 or to 1 ulp less
        # (the same run read from CSV and from ROS 2 quaternions differs by that much)
        j_d = int(np.searchsorted(dist, dist[i] + window_m - BUDGET_TOLERANCE, side="left"))
        j_r = int(np.searchsorted(rot, rot[i] + window_rad - BUDGET_TOLERANCE, side="left"))
        j = min(j_d, j_r)
        if j >= n:
            break
        starts.append(i)
        ends.append(j)
        if pending is None:
            i = j
        elif pending:
            i = pending.pop(0)
        else:
            break
    s = np.asarray(starts, dtype=np.int64)
    e = np.asarray(ends, dtype=np.int64)
    key = key_turning(truth, signed_true, key_m, key_rad)
    rate = turn_rate(truth, signed_true)
    travel = dist / key_m + rot / key_rad
    # a length is the same in every frame: no need to move each window into its start frame
    true_disp = np.hypot(truth.x_m[e] - truth.x_m[s], truth.y_m[e] - truth.y_m[s])
    odo_disp = np.hypot(odometry.x_m[e] - odometry.x_m[s], odometry.y_m[e] - odometry.y_m[s])
    return Windows(
        driven_m=dist[e] - dist[s],
        turned_rad=signed_true[e] - signed_true[s],
        displacement_m=true_disp,
        distance_error_m=odo_disp - true_disp,
        heading_error_rad=(signed_odo[e] - signed_odo[s]) - (signed_true[e] - signed_true[s]),
        window_m=window_m,
        window_rad=window_rad,
        start_s=(truth.stamp_ns[s] - truth.stamp_ns[0]).astype(np.float64) / 1e9
        if len(truth)
        else np.zeros(0),
        start_m=dist[s],
        key_turned_rad=key[e] - key[s],
        turn_rate_change=rate[e] - rate[s],
        start_travel=travel[s],
        end_travel=travel[e],
    )


def begin_indices(odometry: PoseTrack, truth: PoseTrack, windows: Windows) -> npt.NDArray[np.int64]:
    """The pose indices (sorted, the first excluded) where ``windows`` begin."""
    t = (truth.stamp_ns - truth.stamp_ns[0]).astype(np.float64) / 1e9
    idx = np.searchsorted(t, windows.start_s - 1e-9, side="left")
    return np.asarray(idx[1:], dtype=np.int64)
