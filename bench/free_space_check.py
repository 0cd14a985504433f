"""The free-space check (``gridmap_cli.poses.correction.free_space``) on every shared real log.

For each log: the pose graph's track, the scan-matched one under it and the odometry, judged
together as ``--pose auto`` judges them when the graph's track fails; then the graph's track
broken on purpose, judged alone as ``--pose slam`` judges it:

- ``turned N``: its second half turned by N degrees about the pose in its middle;
- ``false closures``: a fifth of its accepted closures (consecutive in the order found) moved
  by 1.5 m and 30 degrees, the graph solved again as the search solves it (one false closure
  among many the robust kernel sets aside, and the track does not change);
- ``every 4th scan`` (the raw bags, ``--quarter``): the graph solved on a quarter of the scans,
  the robot four times as fast between them.

A row per track: the revisits counted, how many contradict, the level a revisit's share must
pass, whether the track fails, and the check's CPU seconds. Prints a markdown table.

    .venv/bin/python bench/free_space_check.py                       # every log
    .venv/bin/python bench/free_space_check.py --logs seattle --quarter
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from real_logs import BAGS, CARMEN, DATA

from gridmap_cli.poses.correction.free_space import (
    FreeSpaceCheck,
    check_poses,
    judged_together,
)
from gridmap_cli.records import PoseTrack, RangeLog

TURNS_DEG = (5.0, 15.0, 45.0)
FALSE_SHARE = 0.2
FALSE_SHIFT = (1.5, math.radians(30.0))


def _path(name: str) -> Path:
    if name.startswith("bag:"):
        return DATA / "slam-benchmark" / BAGS[name[4:]][0]
    return DATA / "carmen" / f"{name}-corrected.log.gz"


def turned_half(track: PoseTrack, degrees: float) -> PoseTrack:
    """``track`` with its second half turned by ``degrees`` about the pose in its middle."""
    h = len(track.x_m) // 2
    cx, cy, a = track.x_m[h], track.y_m[h], math.radians(degrees)
    x, y, theta = track.x_m.copy(), track.y_m.copy(), track.theta_rad.copy()
    x[h:] = cx + math.cos(a) * (track.x_m[h:] - cx) - math.sin(a) * (track.y_m[h:] - cy)
    y[h:] = cy + math.sin(a) * (track.x_m[h:] - cx) + math.cos(a) * (track.y_m[h:] - cy)
    theta[h:] += a
    return dataclasses.replace(track, x_m=x, y_m=y, theta_rad=theta)


def false_closures(result: object) -> PoseTrack | None:
    """The graph's track solved again with a fifth of its closures moved (see the module)."""
    from gridmap_cli.poses.correction.pose_graph import KERNEL_STAGES, PoseGraph
    from gridmap_cli.poses.correction.repair import carried
    from gridmap_cli.poses.correction.slam import SlamResult

    assert isinstance(result, SlamResult)
    if result.graph is None or not result.closures:
        return None
    edges = list(result.graph.edges)
    closures = [k for k, e in enumerate(edges) if e.closure]
    first = len(closures) // 2
    for k in closures[first : first + max(1, int(FALSE_SHARE * len(closures)))]:
        e = edges[k]
        edges[k] = dataclasses.replace(
            e, dx_m=e.dx_m + FALSE_SHIFT[0], dtheta_rad=e.dtheta_rad + FALSE_SHIFT[1]
        )
    graph = PoseGraph(result.graph.initial.copy(), edges)
    poses = graph.optimise(graph.initial.copy(), KERNEL_STAGES)
    return carried(result.scan_matched, result.keyframes, poses)


def every_fourth(log: RangeLog) -> RangeLog:
    """``log`` with the readings of every fourth scan stamp only."""
    r = log.readings
    keep = np.isin(r.stamp_ns, np.unique(r.stamp_ns)[::4])
    fields = {f.name: getattr(r, f.name)[keep] for f in dataclasses.fields(r)}
    return dataclasses.replace(log, readings=dataclasses.replace(r, **fields))


def _timed(track: PoseTrack, points: list[np.ndarray]) -> tuple[FreeSpaceCheck, float]:
    started = time.process_time()
    check = check_poses(track, points)
    return check, time.process_time() - started


def rows_for(name: str, quarter: bool) -> list[str]:
    from gridmap_cli.poses.correction.slam import slam_log
    from gridmap_cli.readers import read_logs
    from gridmap_cli.readers.options import ReadOptions
    from gridmap_cli.robot import robot_from_log

    path = _path(name)
    log = read_logs((path,), None, ReadOptions())
    robot = robot_from_log(path, log.metadata)
    started = time.process_time()
    result = slam_log(log, robot)
    slam_s = time.process_time() - started
    assert result.scans is not None
    points = result.scans.points
    seconds: dict[str, float] = {}
    checks: dict[str, FreeSpaceCheck] = {}
    tracks = {"slam": result.track, "scan-matched": result.scan_matched.track}
    if log.odometry_missing is None:
        tracks["odometry"] = result.scan_matched.odometry
    for label, track in tracks.items():
        checks[label], seconds[label] = _timed(track, points)
    checks = judged_together(checks)
    broken: dict[str, tuple[FreeSpaceCheck, float]] = {}
    for deg in TURNS_DEG:
        broken[f"slam turned {deg:g} deg"] = _timed(turned_half(result.track, deg), points)
    moved = false_closures(result)
    if moved is not None:
        broken["slam, a fifth of its closures false"] = _timed(moved, points)
    if quarter and name.startswith("bag:"):
        thin = slam_log(every_fourth(log), robot)
        assert thin.scans is not None
        broken["slam on every 4th scan"] = _timed(thin.track, thin.scans.points)
    out = []
    for label, check in checks.items():
        out.append(_row(name, label, check, seconds[label], slam_s))
    for label, (check, s) in broken.items():
        out.append(_row(name, label, check, s, slam_s))
    return out


def _row(name: str, label: str, c: FreeSpaceCheck, seconds: float, slam_s: float) -> str:
    return (
        f"| {name} | {label} | {c.revisits:,} | {c.contradicting:,} | {c.level:.3f} | "
        f"{'**fails**' if c.fails else 'passes'} | {seconds:.2f} s ({100 * seconds / slam_s:.1f} "
        "% of slam) |"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", help="comma-separated: bag:intel, bag:aces, bag:freiburg-079, "
                        "or a CARMEN log name (intel, aces, freiburg-079, seattle, acapulco, "
                        "belgioioso); default all")  # fmt: skip
    parser.add_argument("--quarter", action="store_true", help="also slam on every 4th scan")
    args = parser.parse_args(argv)
    names = args.logs.split(",") if args.logs else [f"bag:{b}" for b in BAGS] + list(CARMEN)
    print("| log | track | revisits | contradicting | level | check | cost |")
    print("|---|---|---|---|---|---|---|")
    for name in names:
        for row in rows_for(name, args.quarter):
            print(row, flush=True)


if __name__ == "__main__":
    main()
