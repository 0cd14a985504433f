"""Issue 28's proving ground in one process: ``--pose slam`` on the three raw benchmark bags
(mean error on their relations, on their own stamps) and the six corrected CARMEN logs (APE
RMSE at the scans after an SE(2) fit, against each log's corrected poses).

For the method's work, not the product's table (``make experiment`` has that): any field of
``SlamParams``, ``ClosureParams`` (``closure.NAME``) or the matcher's ``ScanMatchParams``
(``match.NAME``) can be set from the command line, so a constant can be varied x0.5 / x2 on all
nine logs; ``--every N`` keeps every N-th scan (larger steps, faster turns: a harder log).

    nice .venv/bin/python bench/slam_nine.py                       # all nine
    nice .venv/bin/python bench/slam_nine.py --logs aces.bag --set closure.max_search_m=3
    nice .venv/bin/python bench/slam_nine.py --bags --every 3 --json out.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from gridmap_cli.evaluation.relations import read_relations, score_track
from gridmap_cli.poses.correction import slam as slam_module
from gridmap_cli.poses.correction.scan_match import Scans, corrected_track, laser_scans
from gridmap_cli.poses.correction.slam import SlamParams, slam_scans
from gridmap_cli.poses.sync import interpolate_pose, sensors_for_log
from gridmap_cli.poses.track_error import track_error
from gridmap_cli.readers import read_logs
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.records import PoseTrack
from gridmap_cli.robot import robot_from_log

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
BAGS = {
    "intel.bag": "intel.relations",
    "aces.bag": "aces.relations",
    "fr079.bag": "fr079.relations",
}
CARMEN = ("intel", "aces", "freiburg-079", "seattle", "acapulco", "belgioioso")


def _value(text: str, like: object) -> Any:
    if isinstance(like, bool):
        return text.lower() in ("1", "true", "yes")
    if isinstance(like, int):
        return int(text)
    return float(text)


def params_from(sets: list[str]) -> tuple[SlamParams, Any]:
    """SlamParams and the matcher's params with ``NAME=VALUE`` settings applied."""
    slam = SlamParams()
    closure = slam.closure
    match = slam_module.SLAM_MATCH
    for item in sets:
        name, text = item.split("=", 1)
        if name.startswith("closure."):
            key = name.split(".", 1)[1]
            closure = dataclasses.replace(closure, **{key: _value(text, getattr(closure, key))})
        elif name.startswith("match."):
            key = name.split(".", 1)[1]
            match = dataclasses.replace(match, **{key: _value(text, getattr(match, key))})
        else:
            slam = dataclasses.replace(slam, **{name: _value(text, getattr(slam, name))})
    return dataclasses.replace(slam, closure=closure), match


def run(name: str, sets: list[str], every: int) -> dict[str, object]:
    bag = name.endswith(".bag")
    path = (
        DATA
        / ("slam-benchmark" if bag else "carmen")
        / (name if bag else f"{name}-corrected.log.gz")
    )
    data = read_logs((path,), None, ReadOptions())
    robot = robot_from_log(path, data.metadata)
    params, match_params = params_from(sets)
    scans = laser_scans(data, sensors_for_log(data, robot), match_params)
    t = data.poses.stamp_ns
    keep = np.flatnonzero((scans.stamp_ns >= t[0]) & (scans.stamp_ns <= t[-1]))[::every]
    scans = Scans(stamp_ns=scans.stamp_ns[keep], points=[scans.points[k] for k in keep])
    started = time.perf_counter()
    result = slam_scans(scans, data.poses, params, match_params)
    seconds = time.perf_counter() - started
    out: dict[str, object] = {
        "log": name,
        "scans": len(scans),
        "seconds": round(seconds, 1),
        **{k: v for k, v in result.summary().items() if k not in ("scan_match", "seconds")},
    }
    if bag:
        relations = read_relations(DATA / "slam-benchmark" / BAGS[name])
        score = score_track(corrected_track(data.poses, result.match), relations, data.poses)
        out["trans_m"] = round(score.trans_mean_m, 4)
        out["rot_deg"] = round(score.rot_mean_deg, 3)
        out["relations"] = score.count
    else:
        assert data.truth is not None
        m = result.track
        rx, ry, rth, _ = interpolate_pose(data.truth, m.stamp_ns)
        ref = PoseTrack(stamp_ns=m.stamp_ns, x_m=rx, y_m=ry, theta_rad=rth)
        out["ape_m"] = round(track_error(m, ref).ape_rmse_m, 4)
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", nargs="+", default=[*BAGS, *CARMEN])
    parser.add_argument("--bags", action="store_true", help="the three bags only")
    parser.add_argument("--carmen", action="store_true", help="the six CARMEN logs only")
    parser.add_argument("--set", nargs="*", default=[], help="NAME=VALUE (closure.X, match.X)")
    parser.add_argument("--every", type=int, default=1, help="keep every N-th scan")
    parser.add_argument("--json", type=Path, help="append one JSON line per log here")
    args = parser.parse_args(argv)
    logs = list(BAGS) if args.bags else list(CARMEN) if args.carmen else args.logs
    for name in logs:
        row = run(name, args.set, args.every)
        row["set"] = args.set
        row["every"] = args.every
        score = row.get("trans_m", row.get("ape_m", math.nan))
        print(
            f"{name:14s} {score:.4f} rot {row.get('rot_deg', '-')} closures "
            f"{row['closures_accepted']}/{row['candidates']} bend {row['sequential_bend_sigma']} "
            f"fb {row['fallbacks']} {row['seconds']} s warn={row['warning']}",
            flush=True,
        )
        if args.json:
            with args.json.open("a", encoding="utf-8") as f:
                f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
