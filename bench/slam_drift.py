"""``--pose slam`` where the scan matcher drifts far more than on the benchmark's logs: how much
drift the loop closure search takes out before the loops stay open.

An outdoor campus, a laser that sees little, or a long run of corridors leaves the scan-matched
track metres off by the time the robot comes back. Here the drift is made on real scans: each
of the three raw bags of ``../shared/data/slam-benchmark`` is scan-matched as ``--pose slam``
matches it, then every step of the scan-matched track is turned by a steady heading bias per
metre travelled (``--bias``, degrees per metre), and the pose graph (keyframes, closure search,
optimisation, the repair of a failing track) runs on the bent track exactly as it runs on the
matcher's own. The slam track is scored on the benchmark's relations by its rule, beside the
bent scan-matched track, with the free-space check's verdict (a broken track that fails it is
one ``build`` warns of and falls back from, not a silent one).

    nice .venv/bin/python bench/slam_drift.py --jobs 2
    nice .venv/bin/python bench/slam_drift.py --logs aces --bias 0.3

Prints a table; writes nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
import traceback
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from gridmap_cli.evaluation.relations import read_relations, score_track
from gridmap_cli.geometry import compose, inverse, wrap_angle
from gridmap_cli.records import PoseTrack

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "slam-benchmark"
#: row name -> (bag, relations file)
LOGS = {
    "intel": ("intel.bag", "intel.relations"),
    "aces": ("aces.bag", "aces.relations"),
    "freiburg-079": ("fr079.bag", "fr079.relations"),
}


def bent(track: PoseTrack, bias_rad_per_m: float) -> PoseTrack:
    """``track`` with each step's turn increased by ``bias_rad_per_m`` times its length."""
    x, y, th = track.x_m, track.y_m, track.theta_rad
    dx, dy, dth = compose(*inverse(x[:-1], y[:-1], th[:-1]), x[1:], y[1:], th[1:])
    dth = dth + bias_rad_per_m * np.hypot(dx, dy)
    out = np.empty((len(x), 3))
    out[0] = x[0], y[0], th[0]
    for k in range(len(dx)):
        out[k + 1] = compose(out[k, 0], out[k, 1], out[k, 2], dx[k], dy[k], dth[k])
    return PoseTrack(
        stamp_ns=track.stamp_ns.copy(),
        x_m=np.ascontiguousarray(out[:, 0]),
        y_m=np.ascontiguousarray(out[:, 1]),
        theta_rad=np.ascontiguousarray(wrap_angle(out[:, 2])),
    )


def run(job: tuple[str, float]) -> tuple[str, float, str]:
    name, bias = job
    try:
        return name, bias, _run(name, bias)
    except Exception as exc:  # a failure is a result: the row says so, the rest runs
        traceback.print_exc(file=sys.stderr)
        return name, bias, f"{type(exc).__name__}: {exc}".splitlines()[0]


def _run(name: str, bias_deg: float) -> str:
    from gridmap_cli.poses.correction.free_space import verdict
    from gridmap_cli.poses.correction.scan_match import corrected_track, log_scans, match_scans
    from gridmap_cli.poses.correction.slam import SLAM_MATCH, close_loops
    from gridmap_cli.readers import read_logs
    from gridmap_cli.readers.options import ReadOptions
    from gridmap_cli.robot import robot_from_log

    started = time.process_time()
    bag, relations_file = LOGS[name]
    log = read_logs((DATA / bag,), None, ReadOptions())
    relations = read_relations(DATA / relations_file)
    robot = robot_from_log(DATA / bag, log.metadata)
    scans = log_scans(log, robot, SLAM_MATCH)
    match = match_scans(scans, log.poses, SLAM_MATCH)
    match = dataclasses.replace(match, track=bent(match.track, math.radians(bias_deg)))
    result = close_loops(scans, match)
    matched = score_track(corrected_track(log.poses, match), relations, log.poses)
    slam = score_track(corrected_track(log.poses, result.match), relations, log.poses)
    assert result.scans is not None
    check, wide, said = verdict(result.track, result.scans.points, result.free_space)
    if check.fails:
        judged = f"fails ({check.contradicting} of {check.revisits})"
    elif said is not None and wide is not None:
        judged = f"wide look fails ({wide.contradicting} of {wide.revisits})"
    else:
        judged = "passes"
    return (
        f"| {name} | {bias_deg:g} | {matched.trans_mean_m:.3f} m, {matched.rot_mean_deg:.2f}° | "
        f"{slam.trans_mean_m:.3f} m, {slam.rot_mean_deg:.2f}° | "
        f"{len(result.closures):,}/{result.candidates:,} | "
        f"{judged} | {result.widened:g} ({result.widened_for or 'not searched wider'}) | "
        f"{time.process_time() - started:.0f} |"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", default=",".join(LOGS), help="comma-separated")
    parser.add_argument("--bias", default="0.1,0.2,0.3", help="degrees per metre, comma-separated")
    parser.add_argument("--jobs", type=int, default=1, help="runs at a time")
    args = parser.parse_args(argv)
    logs = [n for n in args.logs.split(",") if n]
    bad = [n for n in logs if n not in LOGS]
    if bad:
        parser.error(f"unknown: {', '.join(bad)}")
    if not DATA.is_dir():
        print(f"{DATA} is absent: nothing to measure", file=sys.stderr)
        return
    work = [(n, float(b)) for n in logs for b in args.bias.split(",") if b]
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        rows = list(pool.map(run, work))
    print(
        "| log | bias °/m | bent scan-matched | slam | closures (accepted/tried) "
        "| free-space check | search widened | CPU s |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name, bias, row in rows:
        print(row if row.startswith("|") else f"| {name} | {bias:g} | {row} | | | | | |")


if __name__ == "__main__":
    main()
