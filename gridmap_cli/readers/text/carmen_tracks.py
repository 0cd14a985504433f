"""The pose tracks of a CARMEN log: raw odometry recovered from ODOM increments, the corrected
(or true) track, and one strictly increasing time line.

The published *corrected* logs (the classic SLAM data sets) were rewritten by a SLAM run:
each laser line's pose fields hold the corrected pose, and the first ``ODOM`` line after a scan
*restarts* at that pose (its time stamp is junk: 0, 1e-42, 5.36), the following ones adding the
robot's own odometry increments to it. So

* the relative motion between consecutive ``ODOM`` lines is the robot's odometry increment,
  whatever the restarts did to the frame, because a rigid re-anchoring cancels out of
  ``inverse(p[k-1]) (+) p[k]``;
* across a restart the increment is zero: the restart line is the scan's corrected pose, not a
  motion (the robot was where the ``ODOM`` line before the scan put it, at the scan's own stamp);
* the robot's odometry is the chain of the increments from the first ``ODOM`` pose.

A restart is an ``ODOM`` line that comes first after a laser line and equals that line's pose.
In a raw log this only happens when the robot stands still, where the increment is zero anyway;
a log counts as corrected when some restart *moves* the pose (the scan's pose differs from the
``ODOM`` line before it).

Time: CARMEN stamps are the messages' own ``ipc_timestamp``. File order is the order things
happened (the poses move continuously in it), but the stamps of some logs go backwards by up to
a second, or are coarse or constant. Every timed line gets ``max(its stamp, previous + 1
us)``: time then increases strictly in file order, and moves only where the log's own stamps
disagree with its order. Each scan has a pose on both tracks at its own stamp, so the repair
never misplaces a scan.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import InputFileError
from gridmap_cli.geometry import compose, inverse, wrap_angle
from gridmap_cli.records import MovedStamps, PoseTrack

#: The smallest step between consecutive stamps after the repair: CARMEN prints microseconds.
STAMP_STEP_NS = 1_000

#: Poses closer than this (metres, radians) are the same pose printed twice.
SAME_POSE = 1e-6


@dataclass(frozen=True)
class Event:
    """A timed line of the log, in file order: ``odom``, ``scan`` or ``truepos``.

    ``pose`` is the line's pose (x_m, y_m, theta_rad): the ODOM pose, the scan's robot pose (None
    for RAWLASER), the TRUEPOS true pose. ``scan`` indexes the reader's scans.
    """

    kind: str
    line: int
    stamp_ns: int
    pose: tuple[float, float, float] | None
    scan: int = -1


@dataclass(frozen=True)
class Tracks:
    """What :func:`build_tracks` makes of the events.

    ``event_stamps_ns``: the repaired stamp of every event (a restart gets the stamp before it;
    it is not on any track). ``notes``: metadata lines for people. ``moved``: the odometry
    stamps the repair moved and what the log said (None when it moved none).
    """

    odometry: PoseTrack
    truth: PoseTrack | None
    event_stamps_ns: list[int]
    notes: dict[str, str] = field(default_factory=dict)
    odometry_missing: str | None = None  # why ``odometry`` is no odometry (see RangeLog)
    moved: MovedStamps | None = None


def _same(a: tuple[float, float, float], b: tuple[float, float, float]) -> bool:
    return (
        abs(a[0] - b[0]) <= SAME_POSE
        and abs(a[1] - b[1]) <= SAME_POSE
        and abs(float(wrap_angle(a[2] - b[2]))) <= SAME_POSE
    )


def find_restarts(events: list[Event]) -> tuple[list[bool], int]:
    """Which events are restarts (ODOM re-anchored at the scan before it), and how many of them
    moved the pose (the log is corrected when any did)."""
    restart = [False] * len(events)
    moved = 0
    scan_pose: tuple[float, float, float] | None = None
    odom_before_scan: tuple[float, float, float] | None = None
    last_odom: tuple[float, float, float] | None = None
    for i, event in enumerate(events):
        if event.kind == "scan" and event.pose is not None:
            scan_pose, odom_before_scan = event.pose, last_odom
        elif event.kind == "odom":
            assert event.pose is not None
            if scan_pose is not None and _same(event.pose, scan_pose):
                restart[i] = True
                if odom_before_scan is not None and not _same(scan_pose, odom_before_scan):
                    moved += 1
            scan_pose = None
            last_odom = event.pose
    return restart, moved


def chain_increments(
    poses: npt.NDArray[np.float64], restart: npt.NDArray[np.bool_]
) -> npt.NDArray[np.float64]:
    """The odometry recovered from logged poses, shape (K, 3) in and out.

    Pose k is pose k-1 composed with the relative motion between logged poses k-1 and k; the
    motion into a restart (``restart[k]``) is zero. Starts at the first logged pose.
    """
    out = np.empty_like(poses)
    if len(poses) == 0:
        return out
    px, py, pth = poses[:-1, 0], poses[:-1, 1], poses[:-1, 2]
    ix, iy, ith = inverse(px, py, pth)
    dx, dy, dth = compose(ix, iy, ith, poses[1:, 0], poses[1:, 1], poses[1:, 2])
    moving = ~restart[1:]
    dx, dy, dth = dx * moving, dy * moving, dth * moving
    # heading before each step, unwrapped: theta_k = theta_0 + sum of the turns so far
    theta = poses[0, 2] + np.concatenate([[0.0], np.cumsum(dth)])
    c, s = np.cos(theta[:-1]), np.sin(theta[:-1])
    out[0] = poses[0]
    out[1:, 0] = poses[0, 0] + np.cumsum(c * dx - s * dy)
    out[1:, 1] = poses[0, 1] + np.cumsum(s * dx + c * dy)
    out[:, 2] = wrap_angle(theta)
    return out


def repair_stamps(stamps_ns: list[int]) -> tuple[list[int], int, int, int]:
    """Stamps made strictly increasing in their order: ``max(stamp, previous + 1 us)``.

    Returns the stamps, how many went back from or repeated the log's stamp before them, and
    the largest move (ns).
    """
    out: list[int] = []
    backwards = repeats = largest = 0
    for i, stamp in enumerate(stamps_ns):
        if i:
            backwards += stamp < stamps_ns[i - 1]
            repeats += stamp == stamps_ns[i - 1]
        if out and stamp <= out[-1]:
            largest = max(largest, out[-1] + STAMP_STEP_NS - stamp)
            stamp = out[-1] + STAMP_STEP_NS
        out.append(stamp)
    return out, backwards, repeats, largest


def _track(stamps: list[int], rows: list[tuple[float, float, float]]) -> PoseTrack:
    return PoseTrack.from_rows(np.asarray(stamps, dtype=np.int64), rows)


def _poses(events: list[Event], idx: list[int]) -> list[tuple[float, float, float]]:
    out = []
    for i in idx:
        pose = events[i].pose
        assert pose is not None
        out.append(pose)
    return out


def build_tracks(path: str, events: list[Event], last_line: int) -> Tracks:
    """Raw odometry, reference track and repaired stamps of a CARMEN log's events."""
    restart, moved = find_restarts(events)
    corrected = moved > 0
    timed = [i for i, e in enumerate(events) if not restart[i]]
    fixed, backwards, repeats, largest = repair_stamps([events[i].stamp_ns for i in timed])
    stamps = [0] * len(events)
    for i, stamp in zip(timed, fixed, strict=True):
        stamps[i] = stamp
    for i in range(1, len(events)):
        if restart[i]:
            stamps[i] = stamps[i - 1]

    odom_idx = [i for i, e in enumerate(events) if e.kind == "odom"]
    logged = np.asarray([events[i].pose for i in odom_idx], dtype=np.float64).reshape(-1, 3)
    raw = chain_increments(logged, np.asarray([restart[i] for i in odom_idx], dtype=bool))

    notes: dict[str, str] = {}
    odo_stamps: list[int] = []
    own_ns: list[int] = []  # the lines' own stamps, for a benchmark that names poses by them
    odo_rows: list[tuple[float, float, float]] = []
    if odom_idx:
        current: tuple[float, float, float] | None = None
        k = 0
        for i, event in enumerate(events):
            if event.kind == "odom":
                current = (float(raw[k, 0]), float(raw[k, 1]), float(raw[k, 2]))
                k += 1
                if not restart[i]:
                    odo_stamps.append(stamps[i])
                    own_ns.append(event.stamp_ns)
                    odo_rows.append(current)
            elif event.kind == "scan" and current is not None:
                # the odometry at the scan: where the last ODOM line before it put the robot
                odo_stamps.append(stamps[i])
                own_ns.append(event.stamp_ns)
                odo_rows.append(current)
        n_restarts = sum(restart)
        missing = _only_repeats(events, restart) if corrected else None
        notes["odometry"] = missing or (
            f"the robot's own: the chain of the increments between {len(odom_idx)} ODOM lines"
            + (f", none across the {n_restarts} restarts at scans" if n_restarts else "")
        )
    else:
        for i, event in enumerate(events):
            if event.kind == "scan" and event.pose is not None:
                odo_stamps.append(stamps[i])
                own_ns.append(event.stamp_ns)
                odo_rows.append(event.pose)
        # a corrected data set writes its SLAM poses where a raw log writes the odometry, in
        # both pose fields of a laser line alike: without ODOM lines nothing tells them apart
        missing = (
            "missing: the log has no ODOM lines, and its laser lines' poses may as well be a "
            "corrected log's SLAM poses as the robot's odometry (CARMEN writes both alike); "
            "--pose global maps with them"
        )
        notes["odometry"] = (
            "no ODOM lines: none the log can vouch for; the laser lines' poses are its "
            "reference track (--pose global)"
        )
    if not odo_rows:
        raise InputFileError(
            path, "no odometry: no ODOM lines and no laser line with a pose", last_line
        )

    truth: PoseTrack | None = None
    true_idx = [i for i, e in enumerate(events) if e.kind == "truepos"]
    if true_idx:
        truth = _track([stamps[i] for i in true_idx], _poses(events, true_idx))
        notes["truth"] = f"{len(true_idx)} TRUEPOS lines (--pose global)"
    elif corrected or not odom_idx:
        with_pose = [i for i, e in enumerate(events) if e.kind == "scan" and e.pose is not None]
        truth = _track([stamps[i] for i in with_pose], _poses(events, with_pose))
        what = "corrected poses" if corrected else "poses"
        notes["truth"] = f"the {what} of the {len(with_pose)} laser lines (--pose global)"
    notes["carmen"] = (
        f"corrected log: ODOM restarts from the scan's corrected pose {sum(restart)} times"
        if corrected
        else "raw log: ODOM is the robot's odometry"
        if odom_idx
        else "raw or corrected: without ODOM lines the log does not say"
    )
    moved = sum(a != b for a, b in zip(fixed, (events[i].stamp_ns for i in timed), strict=True))
    if moved:
        notes["stamps"] = (
            f"of {len(timed)} stamps, {backwards} went back and {repeats} repeated the one "
            f"before; {moved} moved forward (at most {largest / 1e9:.3g} s) so that time "
            "increases in file order"
        )
    fixed_odo, logged_odo = np.asarray(odo_stamps, np.int64), np.asarray(own_ns, np.int64)
    differ = fixed_odo != logged_odo
    own = MovedStamps(fixed_odo[differ], logged_odo[differ]) if differ.any() else None
    return Tracks(odometry=_track(odo_stamps, odo_rows), truth=truth, event_stamps_ns=stamps,
                  notes=notes, odometry_missing=missing,
                  moved=own)  # fmt: skip


def _only_repeats(events: list[Event], restart: list[bool]) -> str | None:
    """Why a corrected log has no recoverable odometry, or None: every ODOM line is a restart,
    the pose of the laser line after it or the ODOM line before it repeated, so no increment
    is the robot's own motion."""
    next_scan: list[tuple[float, float, float] | None] = [None] * len(events)
    pose: tuple[float, float, float] | None = None
    for i in range(len(events) - 1, -1, -1):  # the pose of the first laser line after each
        next_scan[i] = pose
        if events[i].kind == "scan" and events[i].pose is not None:
            pose = events[i].pose
    count = 0
    before: tuple[float, float, float] | None = None
    for i, event in enumerate(events):
        if event.kind != "odom":
            continue
        count += 1
        after = next_scan[i]
        assert event.pose is not None
        repeats = (after is not None and _same(event.pose, after)) or (
            before is not None and _same(event.pose, before)
        )
        if not restart[i] and not repeats:
            return None
        before = event.pose
    return (
        f"missing: the {count} ODOM lines only repeat the laser lines' corrected poses, so no "
        "odometry is recoverable (--pose global maps with the corrected poses)"
    )
