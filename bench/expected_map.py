"""The analytic error-aware map against the sampled expected map (issue 19 item 2), simulated.

For each sample world at drift 0 and 1 (one seed), with f and g calibrated on another run as
``make experiment`` does: NLL of the standard map, the error-aware map and the expected map of
K sampled tracks, and the seconds each took (in-process).

    .venv/bin/python bench/expected_map.py [--samples K] [--seed S] [--out DIR]
"""

from __future__ import annotations

import argparse
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
from gridmap_cli.mapping.pipeline import BuildOptions, build_map
from gridmap_cli.poses.odometry_error import load_odometry_error
from gridmap_cli.poses.sync import sensors_for_log
from gridmap_cli.readers import read_log
from gridmap_cli.robot import load_robot


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--seed", type=int, default=21)
    parser.add_argument("--out", type=Path, default=Path("out/expected"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    robot = load_robot(experiment.ROBOT)
    truths = experiment.load_truths(experiment.WORLDS)
    print("| world | drift | standard | error-aware | expected (K) | s std / aware / expected |")
    print("|---|---|---|---|---|---|")
    for drift in (0.0, 1.0):
        odometry = load_odometry_error(experiment.calibrate(args.out, drift))
        for world, truth in truths.items():
            stem = f"{world}_drift{experiment.drift_name(drift)}_seed{args.seed}"
            path = experiment.simulate(world, args.out / f"{stem}.csv", args.seed, drift, None)
            log = read_log(path)
            assert log.truth is not None
            region = sensed_region(truth.world, log.truth, sensors_for_log(log, robot))
            start = odometry_frame_in_world(log)
            scores, seconds = [], []
            for how in ("standard", "error-aware", "expected"):
                t0 = time.perf_counter()
                samples = 0 if how == "error-aware" else args.samples
                mode = "standard" if how == "standard" else "error-aware"
                options = BuildOptions(mode=mode, odometry_error=odometry, error_samples=samples)
                result = build_map(log, robot, options)
                seconds.append(time.perf_counter() - t0)
                pmap = ProbabilityMap.from_occupancy_map(result.map, 0.65)
                scores.append(evaluate_map(pmap, truth.walls, truth.spec, region, start).nll)
            print(
                f"| {world} | {drift:g} | {scores[0]:.4f} | {scores[1]:.4f} | {scores[2]:.4f} "
                f"({args.samples}) | {seconds[0]:.1f} / {seconds[1]:.1f} / {seconds[2]:.1f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
