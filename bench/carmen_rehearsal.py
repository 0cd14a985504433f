"""A rehearsal of issue 19's held-out check on more cases cut from the shared CARMEN logs.

The maintainers check the claim on held-out logs: ``gridmap calibrate`` on the first half, the
second half mapped with that calibration, scored against the reference. Our own figures come from
six cases (``bench/carmen_experiment.py``: both halves of three logs). This script cuts more
cases from the same logs, to see how often the bound (error-aware NLL <= 1.02x the best
drift-blind map) fails and why:

* ``split-F``: calibrate on the first F of the log (by time), map the rest (F = 30 to 70 %);
* ``half-quarter``: calibrate on the first half, map only the next quarter;
* ``short-Q``: calibrate on the quarter (or the 15 %) just before the half, map the second half;
* ``other-log``: calibrate on the whole of another log (``CROSS`` of the experiment), map the
  second half.

Each case scores ``standard``, ``standard-corrected`` and ``error-aware`` as the experiment does;
``error-aware-perfect`` is the standard map again (tests/test_error_aware_equivalence.py), so its
score is the standard one. The drift is the largest distance between the mapped part's odometry
and the reference.

    .venv/bin/python bench/carmen_rehearsal.py                 # every log and case (~5 min)
    .venv/bin/python bench/carmen_rehearsal.py --logs aces --cases split-30,other-log
    .venv/bin/python bench/carmen_rehearsal.py --walk-scale 0.25   # narrower spreads
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from calibration_transfer import placed
from carmen_experiment import (
    CROSS,
    LOGS,
    MODES,
    ROOT,
    calibrate,
    duration_s,
    gridmap,
    log_path,
    odometry_drift_m,
    perfect_file,
    reference,
    window,
)

from gridmap_cli.evaluation.evaluate import (
    evaluate_map,
    load_probability_map,
    load_truth,
    odometry_frame_in_world,
    sensed_region,
)
from gridmap_cli.mapping.selection import Selection, apply_selection
from gridmap_cli.poses.calibration.windows import truth_at_odometry
from gridmap_cli.poses.odometry_error import (
    correct_track,
    load_odometry_error,
    save_odometry_error,
)
from gridmap_cli.poses.sync import sensors_for_log
from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise, propagate
from gridmap_cli.readers import read_log
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import robot_from_log


@dataclass(frozen=True)
class Case:
    """Calibrate on [cal_from, cal_to), map [map_from, map_to): fractions of the log's duration
    (None = its end); ``other`` calibrates on the whole of another log instead."""

    name: str
    cal_from: float
    cal_to: float | None
    map_from: float
    map_to: float | None
    other: bool = False


CASES = (
    Case("half", 0.0, 0.5, 0.5, None),
    Case("half-reversed", 0.5, None, 0.0, 0.5),
    Case("split-30", 0.0, 0.3, 0.3, None),
    Case("split-40", 0.0, 0.4, 0.4, None),
    Case("split-60", 0.0, 0.6, 0.6, None),
    Case("split-70", 0.0, 0.7, 0.7, None),
    Case("half-quarter", 0.0, 0.5, 0.5, 0.75),
    Case("short-25", 0.25, 0.5, 0.5, None),
    Case("short-15", 0.35, 0.5, 0.5, None),
    Case("other-log", 0.0, None, 0.5, None, other=True),
)
SCORED = ("standard", "standard-corrected", "error-aware")
BLIND = ("standard", "standard-corrected")
EVERY = 1.02


def _at(frac: float | None, total: float) -> float | None:
    return None if frac is None or (frac == 0.0) else frac * total


def scaled(calibration: Path, k: float) -> Path:
    """A copy of ``calibration`` with its random walks times ``k`` (``calibration`` itself at
    1): what a spread that wide or narrow would have scored."""
    if k == 1.0:
        return calibration
    m = load_odometry_error(calibration)
    walks = ("range_m_per_sqrt_m", "bearing_rad_per_sqrt_rad", "heading_rad_per_sqrt_m",
             "lateral_m_per_sqrt_m")  # fmt: skip
    path = calibration.with_name(f"{calibration.stem}_walks-x{k:g}.yaml")
    save_odometry_error(replace(m, **{w: getattr(m, w) * k for w in walks}), path)
    return path


def run(
    logs: tuple[str, ...], cases: tuple[Case, ...], out: Path, walk_scale: float = 1.0
) -> list[tuple]:
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    whole: dict[str, Path] = {}
    for name in logs:
        path = log_path(name)
        data = read_log(path)
        robot = robot_from_log(path, data.metadata)
        total = duration_s(data)
        truth = load_truth(reference(name, out))
        standard: dict[tuple, float] = {}
        for case in cases:
            if case.other:
                other = CROSS[name]
                if other not in whole:
                    whole[other] = calibrate(other, out, None, None, "whole")
                cal = whole[other]
            else:
                a, b = _at(case.cal_from, total), _at(case.cal_to, total)
                cal = calibrate(name, out, a, b, case.name)
            start, end = _at(case.map_from, total), _at(case.map_to, total)
            texts = tuple(None if v is None else f"{v:.3f}" for v in (start, end))
            selected = apply_selection(data, Selection.parse((), *texts), robot).log
            true_path = selected.require_truth("the rehearsal scores against the reference")
            region = sensed_region(truth.world, true_path, sensors_for_log(selected, robot))
            pose0 = odometry_frame_in_world(selected)
            drift = odometry_drift_m(selected)
            spread = spread_ratio(selected, cal)
            nll = {}
            walked = scaled(cal, walk_scale)
            for mode in SCORED:
                key = (start, end)
                if mode == "standard" and key in standard:
                    nll[mode] = standard[key]
                    continue
                used = walked if mode == "error-aware" else cal
                args = [
                    a.replace("{cal}", str(used)).replace("{perfect}", str(perfect_file(out)))
                    for a in MODES[mode]
                ]
                image = out / f"{name}_{case.name}_{mode}.png"
                gridmap(
                    "build", str(path), "-o", str(image), "--map-mode", "scale", "--force",
                    "--quiet", *window(start, end), *args,
                )  # fmt: skip
                pmap = load_probability_map(image.with_suffix(".yaml"))
                e = evaluate_map(pmap, truth.walls, truth.spec, region, pose0, truth.known)
                nll[mode] = e.nll
                if mode == "standard":
                    standard[key] = e.nll
            best = min(BLIND, key=nll.__getitem__)
            row = (name, case.name, drift, spread, nll["error-aware"], best, nll[best])
            rows.append(row)
            print(_line(row), flush=True)
    return rows


def spread_ratio(part: RangeLog, calibration: Path) -> float:
    """The mapped part's actual position error over what the calibration's random walks
    predict there (root mean squares over the part, the odometry corrected by the biases and
    placed at the part's first reference pose): above 1 the spread is too narrow."""
    model = load_odometry_error(calibration)
    odometry, truth = truth_at_odometry(part)
    corrected = placed(correct_track(odometry, model), truth)
    cov = propagate(corrected, StepNoise.of(model.random_part())).at(corrected.stamp_ns)
    err = (corrected.x_m - truth.x_m) ** 2 + (corrected.y_m - truth.y_m) ** 2
    predicted = float(np.mean(cov[:, 0, 0] + cov[:, 1, 1]))
    return math.sqrt(float(np.mean(err)) / predicted) if predicted > 0 else math.inf


def _line(row: tuple) -> str:
    name, case, drift, spread, ea, best, blind = row
    ratio = ea / blind
    flag = "" if ratio <= EVERY else " FAIL"
    return (
        f"| {name} | {case} | {drift:.1f} | {spread:.2f} | {ea:.3f} | {best} | {blind:.3f} "
        f"| {ratio:.3f}{flag} |"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", default=",".join(LOGS))
    parser.add_argument("--cases", default=",".join(c.name for c in CASES))
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "carmen-rehearsal")
    parser.add_argument(
        "--walk-scale",
        type=float,
        default=1.0,
        help="the error-aware map's random walks times this (the calibration's at 1)",
    )
    args = parser.parse_args(argv)
    wanted = set(args.cases.split(","))
    cases = tuple(c for c in CASES if c.name in wanted)
    started = time.perf_counter()
    print(
        "| log | case | drift (m) | actual / predicted error | error-aware NLL "
        "| best drift-blind | its NLL | ratio |"
    )
    print("|---|---|---|---|---|---|---|---|")
    rows = run(tuple(n for n in args.logs.split(",") if n), cases, args.out, args.walk_scale)
    ratios = [r[4] / r[6] for r in rows]
    failed = sum(r > EVERY for r in ratios)
    print(f"\n{failed} of {len(ratios)} cases over {EVERY}x; mean ratio "
          f"{sum(ratios) / len(ratios):.3f}, worst {max(ratios):.3f}")  # fmt: skip
    print(f"{time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
