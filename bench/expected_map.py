"""The analytic error-aware map against the sampled expected map (issue 19 item 2), simulated.

For each sample world at drift 0 and 1 (each seed), with f and g calibrated on another run as
``make experiment`` does: NLL of the standard map, the error-aware map and the expected map of
K sampled tracks (the product's fast map), its oracle (K full-resolution standard builds of
sampled tracks, averaged) and the seconds each took (in-process).

    .venv/bin/python bench/expected_map.py [--samples K] [--oracle K] [--seeds S,..] [--worlds W]
        [--drifts D] [--correct-odometry] [--out DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import experiment

from gridmap_cli.evaluation.evaluate import (
    ProbabilityMap,
    evaluate_map,
    odometry_frame_in_world,
    sensed_region,
)
from gridmap_cli.mapping import expected_oracle
from gridmap_cli.mapping.grid import OccupancyMap
from gridmap_cli.mapping.pipeline import BuildOptions, build_map, corrected_for_build, plan_build
from gridmap_cli.poses.odometry_error import load_odometry_error
from gridmap_cli.poses.sync import sensors_for_log
from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise, sample_tracks
from gridmap_cli.readers import read_log
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RobotDescription, load_robot


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--seeds", default="21", help="comma-separated simulation seeds")
    parser.add_argument(
        "--correct-odometry", action="store_true", help="map the corrected track (build's flag)"
    )
    parser.add_argument("--out", type=Path, default=Path("out/expected"))
    parser.add_argument("--worlds", default=",".join(experiment.WORLDS), help="comma-separated")
    parser.add_argument("--drifts", default="0,1", help="comma-separated")
    parser.add_argument(
        "--oracle", type=int, default=16, help="samples of the full-resolution oracle (0: none)"
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    robot = load_robot(experiment.ROBOT)
    truths = experiment.load_truths(tuple(args.worlds.split(",")))
    print(
        "| world | drift | standard | analytic | expected (K) | oracle (K) | expected / standard "
        "| s std / analytic / expected / oracle |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for drift in (float(d) for d in args.drifts.split(",")):
        odometry = load_odometry_error(experiment.calibrate(args.out, drift))
        for world, seed in ((w, s) for w in truths for s in map(int, args.seeds.split(","))):
            truth = truths[world]
            stem = f"{world}_drift{experiment.drift_name(drift)}_seed{seed}"
            path = experiment.simulate(world, args.out / f"{stem}.csv", seed, drift, None)
            log = read_log(path)
            assert log.truth is not None
            region = sensed_region(truth.world, log.truth, sensors_for_log(log, robot))
            start = odometry_frame_in_world(log)
            scores, seconds = [], []
            for how in ("standard", "analytic", "expected", "oracle"):
                t0 = time.perf_counter()
                samples = 0 if how == "analytic" else args.samples
                mode = "standard" if how == "standard" else "error-aware"
                options = BuildOptions(
                    mode=mode, odometry_error=odometry, error_samples=samples,
                    correct_odometry=args.correct_odometry,
                )  # fmt: skip
                if how == "oracle":
                    if args.oracle == 0:
                        scores.append(float("nan"))
                        seconds.append(0.0)
                        continue
                    omap = oracle(log, robot, options, args.oracle)
                else:
                    omap = build_map(log, robot, options).map
                seconds.append(time.perf_counter() - t0)
                pmap = ProbabilityMap.from_occupancy_map(omap, 0.65)
                scores.append(evaluate_map(pmap, truth.walls, truth.spec, region, start).nll)
            print(
                f"| {world} {seed} | {drift:g} | {scores[0]:.4f} | {scores[1]:.4f} "
                f"| {scores[2]:.4f} "
                f"({args.samples}) | {scores[3]:.4f} ({args.oracle}) | "
                f"{scores[2] / scores[0]:.3f} | " + " / ".join(f"{t:.1f}" for t in seconds) + " |",
                flush=True,
            )


def oracle(log: RangeLog, robot: RobotDescription, options: BuildOptions, k: int) -> OccupancyMap:
    """The expected map the slow way: ``k`` full standard builds of sampled tracks."""
    if options.correct_odometry:
        log, options = corrected_for_build(log, options)
    standard = dataclasses.replace(options, mode="standard")
    plan = plan_build(log, robot, standard)
    assert options.odometry_error is not None
    noise = StepNoise.of(options.odometry_error)
    tracks = sample_tracks(log.poses, noise, k, options.error_seed)
    return expected_oracle.exact(plan, tracks, standard.clamp_p, standard.batch_size)


if __name__ == "__main__":
    main()
