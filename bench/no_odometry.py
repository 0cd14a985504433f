"""A laser without odometry: the benchmark's raw bags mapped by ``--pose slam`` from the scans.

Each bag in ``../shared/data/slam-benchmark/`` is read as ``build`` reads it, then its odometry is
dropped in memory (the pose track emptied and ``odometry_missing`` set, as the reader leaves a
recording with no ``/odom`` and no ``odom -> base_link`` transforms): no new bag is written. The
motion then comes from the scans (:mod:`gridmap_cli.poses.correction.scan_odometry`), the pose
graph corrects it, and the track is scored on the bag's relations as ``bench/real_logs.py`` scores
it (mean ± standard deviation of the translational error, m; rotational, deg). Also printed: the
scan odometry's own score, the relations under and over 20 s apart (local motion against loops),
the closures, the free-space check's verdict, and the CPU seconds (all threads of the process) of
the motion and of the slam pipeline.

    .venv/bin/python bench/no_odometry.py                    # every bag
    .venv/bin/python bench/no_odometry.py --logs aces,freiburg-079
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.real_logs import BAGS, DATA, PUBLISHED  # noqa: E402
from gridmap_cli.evaluation.relations import Relations  # noqa: E402
from gridmap_cli.poses.correction.free_space import FreeSpaceCheck  # noqa: E402
from gridmap_cli.records import PoseTrack  # noqa: E402

#: Relations closer in time than this are local (the motion's own); further apart, loops.
LOCAL_S = 20.0


def _score(track: PoseTrack, relations: Relations, odometry: PoseTrack, split: bool = False) -> str:
    from gridmap_cli.evaluation.relations import score_track

    s = score_track(track, relations, odometry)
    text = (
        f"{s.trans_mean_m:.3f} ± {s.trans_std_m:.3f} m, {s.rot_mean_deg:.2f} ± "
        f"{s.rot_std_deg:.2f} deg ({s.count} relations)"
    )
    if not split:
        return text
    span = (relations.t2_ns - relations.t1_ns) / 1e9
    parts = []
    for name, keep in (("local", np.abs(span) < LOCAL_S), ("long", np.abs(span) >= LOCAL_S)):
        part = dataclasses.replace(
            relations, **{f.name: getattr(relations, f.name)[keep]
                          for f in dataclasses.fields(relations)
                          if isinstance(getattr(relations, f.name), np.ndarray)}
        )  # fmt: skip
        p = score_track(track, part, odometry)
        parts.append(f"{name} {p.trans_mean_m:.3f} m ({p.count})")
    return f"{text}; {', '.join(parts)}"


def run(name: str) -> None:
    from gridmap_cli.evaluation.relations import read_relations
    from gridmap_cli.poses.correction.free_space import check_poses
    from gridmap_cli.poses.correction.scan_match import corrected_track
    from gridmap_cli.poses.correction.scan_odometry import with_scan_motion
    from gridmap_cli.poses.correction.slam import slam_log
    from gridmap_cli.readers import read_logs
    from gridmap_cli.readers.options import ReadOptions
    from gridmap_cli.robot import robot_from_log

    bag, relations_file = BAGS[name]
    path = DATA / "slam-benchmark" / bag
    data = read_logs((path,), None, ReadOptions())
    empty = PoseTrack(
        stamp_ns=np.zeros(0, np.int64), x_m=np.zeros(0), y_m=np.zeros(0), theta_rad=np.zeros(0)
    )
    alone = dataclasses.replace(data, poses=empty, odometry_missing="missing: left out")
    relations = read_relations(DATA / "slam-benchmark" / relations_file)
    robot = robot_from_log(path, alone.metadata)
    started = time.process_time()
    moving = with_scan_motion(alone, robot)
    motion_s = time.process_time() - started
    print(f"{name}: motion from the scans {_score(moving.poses, relations, moving.poses, True)} "
          f"[{motion_s:.0f} s CPU]", flush=True)  # fmt: skip
    started = time.process_time()
    result = slam_log(moving, robot)
    slam_s = time.process_time() - started
    track = corrected_track(moving.poses, result.match)
    s = result.summary()
    check = "" if result.scans is None else _check(check_poses(result.track, result.scans.points))
    print(
        f"{name}: slam {_score(track, relations, moving.poses, True)} "
        f"[{slam_s:.0f} s CPU; {motion_s + slam_s:.0f} s with the motion]; "
        f"{s['closures_accepted']:,} closures, {s['closures_rejected']:,} rejected"
        f"{'; ' + result.warning if result.warning else ''}{check}; "
        f"GMapping with odometry {PUBLISHED[name][0]:.3f} m",
        flush=True,
    )


def _check(check: FreeSpaceCheck) -> str:
    verdict = f"FAILS: {check.reason()}" if check.fails else "passes"
    return f"; free-space check: {check.contradicting} of {check.revisits} contradict, {verdict}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", default=",".join(BAGS), help="comma-separated: " + ",".join(BAGS))
    args = parser.parse_args()
    for name in args.logs.split(","):
        run(name)


if __name__ == "__main__":
    main()
