"""Every closure the pose graph accepts on one log, scored against a reference track: which were
false, how far from their guesses they were found, and whether the graph kept them.

A stress row that fails says little about why; the closures say more. This runs ``--pose slam``
on one log (or one of ``bench/slam_stress.py``'s variants of it, jittered as
``bench/slam_spread.py`` jitters), records each closure ``verify`` accepts, and scores it
against a reference track by scan index:

- a CARMEN log of ``../shared/data/carmen``: its corrected poses at the scans' stamps;
- a raw benchmark bag (``--bag``; it has no poses to compare with): the slam track of the full
  log, saved once with ``--save``; only the variants that keep every scan (``full``, ``beams-1/2``,
  ``interleave-2``, ``range-5.6``) keep its scan indices.

A closure is *false* where its relative pose is more than ``--false-m`` off the reference's.
For each false one it prints its scans, its error, how far from its guess ``verify`` found it
(over ``coarse_from_m``, the far closures' judge was asked), its inlier share, and whether the
final graph holds it.

    nice .venv/bin/python bench/closure_trace.py aces --bag --save /tmp/aces-full.npz
    nice .venv/bin/python bench/closure_trace.py aces --bag --variant range-5.6 --seed 5 \\
        --reference /tmp/aces-full.npz
    nice .venv/bin/python bench/closure_trace.py belgioioso --variant from-1/3 --seed 1
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from real_logs import CARMEN, jittered
from slam_stress import DATA as BAGS
from slam_stress import LOGS, VARIANTS, slam_tracks

from gridmap_cli.poses.correction.loop_closure import Closure

CARMEN_DATA = BAGS.parent / "carmen"
#: the variants that keep every scan of the log, so a reference by scan index still applies
SAME_SCANS = ("full", "beams-1/2", "interleave-2", "range-5.6")


@dataclass(frozen=True)
class Accepted:
    """A closure ``verify`` accepted: its nodes' scans, the scan offered as its target, how far
    (m) from its guess it was found, and the closure."""

    scan_i: int
    scan_j: int
    offered: int
    from_guess_m: float
    closure: Closure


def traced(log: Any, robot: Any) -> tuple[Any, str | None, list[Accepted]]:
    """The slam run of ``log``, its free-space verdict, and every closure ``verify`` accepted."""
    import gridmap_cli.poses.correction.slam as slam_module
    from gridmap_cli.geometry import inverse

    relative, verify = slam_module.relative, slam_module.verify
    estimate: dict[str, np.ndarray] = {}
    accepted: list[Accepted] = []

    def spy_relative(poses: np.ndarray, i: int, j: int) -> tuple[float, float, float]:
        estimate["poses"] = poses  # the estimate the next guess is made from
        return relative(poses, i, j)

    def spy_verify(i: int, j: int, guess: Any, submaps: Any, *rest: Any) -> Any:
        closure = verify(i, j, guess, submaps, *rest)
        if closure is not None:
            gx, gy, _ = relative(estimate["poses"], i, closure.j)
            x, y, _ = inverse(*(np.asarray(v) for v in (closure.dx_m, closure.dy_m,
                                                          closure.dtheta_rad)))  # fmt: skip
            nodes = submaps.nodes
            accepted.append(Accepted(
                int(nodes[i]), int(nodes[closure.j]), int(nodes[j]),
                math.hypot(float(x) - gx, float(y) - gy), closure,
            ))  # fmt: skip
        return closure

    slam_module.relative, slam_module.verify = spy_relative, spy_verify
    try:
        slam, _, verdict = slam_tracks(log, robot)
    finally:
        slam_module.relative, slam_module.verify = relative, verify
    return slam, verdict, accepted


def main(argv: list[str] | None = None) -> None:
    from gridmap_cli.poses.correction.loop_closure import ClosureParams, relative
    from gridmap_cli.poses.sync import interpolate_pose
    from gridmap_cli.readers import read_logs
    from gridmap_cli.readers.options import ReadOptions
    from gridmap_cli.robot import robot_from_log

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", choices=sorted({*LOGS, *CARMEN}))
    parser.add_argument("--bag", action="store_true", help="the raw benchmark bag, not CARMEN")
    parser.add_argument("--variant", default="full", choices=list(VARIANTS))
    parser.add_argument("--seed", type=int, help="odometry jitter seed (default: as read)")
    parser.add_argument("--reference", type=Path, help="a bag's full slam track (--save)")
    parser.add_argument("--save", type=Path, help="write the slam track by scan index (.npz)")
    parser.add_argument(
        "--false-m", type=float, default=0.5, help="a closure this far off is false"
    )
    args = parser.parse_args(argv)

    carmen = not args.bag
    if args.log not in (CARMEN if carmen else LOGS):
        parser.error(f"no {'CARMEN log' if carmen else 'bag'} {args.log!r}")
    if args.reference and not args.reference.exists():
        parser.error(f"{args.reference} is not there")
    if not carmen and args.reference and args.variant not in SAME_SCANS:
        parser.error(f"{args.variant} drops scans: a reference by scan index does not apply")
    path = CARMEN_DATA / f"{args.log}-corrected.log.gz" if carmen else BAGS / LOGS[args.log][0]
    if not path.exists():
        parser.error(f"{path} is not there")
    data = read_logs((path,), None, ReadOptions())
    log = VARIANTS[args.variant](jittered(data, args.seed))
    slam, verdict, accepted = traced(log, robot_from_log(path, log.metadata))
    track = slam.track
    poses = np.column_stack([track.x_m, track.y_m, track.theta_rad])
    if args.save:
        np.savez(args.save, track=poses)
    print(
        f"{args.log} {args.variant}, seed {args.seed}: {len(slam.closures)} closures of "
        f"{slam.candidates} tried; warning: {slam.warning}; free-space check: {verdict}"
    )
    if carmen:
        assert data.truth is not None
        x, y, th, known = interpolate_pose(data.truth, track.stamp_ns)
        reference = np.column_stack([x, y, th])
    elif args.reference:
        reference = np.load(args.reference)["track"]
        known = np.ones(len(reference), dtype=bool)
        if len(reference) != len(poses):
            parser.error(f"{args.reference} has {len(reference)} scans, this run {len(poses)}")
    else:
        print("no reference: give --reference (a bag's full track, made with --save)")
        return
    far_m = ClosureParams().coarse_from_m
    final = {(c.i, c.j) for c in slam.closures}
    seen: set[tuple[int, int]] = set()
    false = far = false_final = 0
    for a in accepted:
        c = a.closure
        if (c.i, c.j) in seen or not (known[a.scan_i] and known[a.scan_j]):
            continue
        seen.add((c.i, c.j))
        far += a.from_guess_m > far_m
        rx, ry, _ = relative(reference, a.scan_j, a.scan_i)  # j's pose in i's frame
        error = math.hypot(rx - c.dx_m, ry - c.dy_m)
        if error <= args.false_m:
            continue
        false += 1
        false_final += (c.i, c.j) in final
        print(
            f"  false: scan {a.scan_i} onto {a.scan_j} (offered {a.offered}), {error:.2f} m "
            f"off, found {a.from_guess_m:.2f} m from its guess, inliers "
            f"{c.inlier_fraction:.2f}, {'held' if (c.i, c.j) in final else 'dropped'}"
        )
    print(
        f"{len(seen)} closures accepted at verification ({far} found over {far_m:g} m from "
        f"their guesses), {false} false, {false_final} of them held by the final graph"
    )


if __name__ == "__main__":
    main()
