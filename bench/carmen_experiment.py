"""The real part of ``make experiment``: the error-aware claim on the CARMEN logs (issue 9).

For each corrected log of ``../shared/data/carmen`` (Intel, ACES, Freiburg 079):

* the **reference map** is built from the corrected (SLAM) poses, ``gridmap build --pose global
  --mode error-aware`` with f = g = 0, trinary: with no pose error the error-aware mode maps as
  the standard one, so this is the standard map of the corrected poses (the frequency-count
  error-aware model this was chosen for, when it drew walls the standard map lost, is gone);
* the log is cut in two halves by time; f and g are calibrated (``gridmap calibrate``) on one
  half and the maps of the *other* half are built with them, so no reported half is ever
  calibrated on; the first minutes of the log (where the drift is still small) are built with
  the second half's calibration; a fourth error-aware map of each half uses the whole of
  another log's calibration (a different robot: what a user without a reference would borrow);
* every map is built from the robot's own odometry in scale mode and scored as ``gridmap
  evaluate --log --start --end`` scores it: over the reference's known cells that the window's
  corrected path could have sensed, the map placed by the window's first reference pose.

    .venv/bin/python bench/carmen_experiment.py          # prints the scores; make experiment
                                                          # writes them into docs/experiments.md
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass
from pathlib import Path

from gridmap_cli.cli import cli
from gridmap_cli.evaluation.evaluate import (
    Evaluation,
    Pose,
    Truth,
    evaluate_map,
    load_probability_map,
    load_truth,
    odometry_frame_in_world,
    sensed_region,
)
from gridmap_cli.mapping.pipeline import BuildOptions, build_map
from gridmap_cli.mapping.selection import Selection, apply_selection
from gridmap_cli.poses.odometry_error import OdometryError, load_odometry_error
from gridmap_cli.poses.sync import sensors_for_log
from gridmap_cli.readers import read_log
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import robot_from_log
from gridmap_cli.writers.map_image import write_map

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "carmen"
LOGS = ("intel", "aces", "freiburg-079")
#: The first minutes of a log, where its drift is still small.
FIRST_S = 180.0
#: Build arguments of each mode; ``{cal}`` is the other half's calibration, ``{cross}``
#: another log's.
MODES: dict[str, list[str]] = {
    "standard": ["--mode", "standard"],
    "error-aware-f0g0": ["--mode", "error-aware", "--odometry-coefficient", "range_m_per_m=0"],
    "error-aware": ["--mode", "error-aware", "--odometry-error", "{cal}"],
    "error-aware-other-log": ["--mode", "error-aware", "--odometry-error", "{cross}"],
    # the analytic model (the standard evidence faded by the pose spread), built in-process
    # until build has an option for it (--error-samples 0)
    "error-aware-analytic": ["{cal}"],
}
#: The claim: error-aware against the best of these drift-blind mappers.
DRIFT_BLIND = ("standard", "error-aware-f0g0")
CLAIMED = "error-aware"
#: The log whose whole-log calibration each log borrows for ``error-aware-other-log``.
CROSS = {"intel": "aces", "aces": "intel", "freiburg-079": "aces"}


@dataclass(frozen=True)
class Part:
    """A window of a log (seconds from its start; None = open) and the calibration half."""

    name: str
    start_s: float | None
    end_s: float | None
    calibrated_on: str


@dataclass(frozen=True)
class RealRun:
    log: str
    part: str
    mode: str
    evaluation: Evaluation
    map_yaml: Path
    map_to_world: Pose


def gridmap(*args: str) -> None:
    """Run one ``gridmap`` command in-process; a failure stops the experiment."""
    try:
        cli.main(args=list(args), prog_name="gridmap", standalone_mode=False)
    except Exception as exc:
        raise SystemExit(f"gridmap {' '.join(args)}: {exc}") from exc


def window(start: float | None, end: float | None) -> list[str]:
    out = []
    if start is not None:
        out += ["--start", f"{start:.3f}"]
    if end is not None:
        out += ["--end", f"{end:.3f}"]
    return out


def log_path(name: str) -> Path:
    return DATA / f"{name}-corrected.log.gz"


def duration_s(log: RangeLog) -> float:
    stamps = log.poses.stamp_ns
    first = min(int(stamps[0]), int(log.readings.stamp_ns[0]))
    return (int(stamps[-1]) - first) / 1e9


def reference(name: str, out: Path) -> Path:
    image = out / f"{name}_reference.png"
    gridmap(
        "build", str(log_path(name)), "--pose", "global", "-o", str(image), "--force", "--quiet",
        *MODES["error-aware-f0g0"][:],
    )  # fmt: skip
    return image.with_suffix(".yaml")


def calibrate(name: str, out: Path, start: float | None, end: float | None, tag: str) -> Path:
    path = out / f"{name}_calibration_{tag}.yaml"
    gridmap(
        "calibrate", str(log_path(name)), "-o", str(path), "--force", "--quiet",
        *window(start, end),
    )  # fmt: skip
    return path


def run_log(
    name: str, out: Path, cross: dict[str, Path], modes: tuple[str, ...]
) -> tuple[list[RealRun], dict[str, OdometryError], Truth]:
    path = log_path(name)
    data = read_log(path)
    robot = robot_from_log(path, data.metadata)
    mid = 0.5 * duration_s(data)
    ref_yaml = reference(name, out)
    truth = load_truth(ref_yaml)
    cals = {
        "first half": calibrate(name, out, None, mid, "first"),
        "second half": calibrate(name, out, mid, None, "second"),
    }
    parts = (
        Part("first half", None, mid, "second half"),
        Part("second half", mid, None, "first half"),
        Part(f"first {FIRST_S / 60:g} min", None, FIRST_S, "second half"),
    )
    runs = []
    for part in parts:
        selected = apply_selection(data, Selection.parse((), *_texts(part)), robot).log
        true_path = selected.require_truth("the experiment scores against the reference")
        region = sensed_region(truth.world, true_path, sensors_for_log(selected, robot))
        start = odometry_frame_in_world(selected)
        for mode in modes:
            args = [
                a.replace("{cal}", str(cals[part.calibrated_on])).replace(
                    "{cross}", str(cross[name])
                )
                for a in MODES[mode]
            ]
            stem = f"{name}_{part.name.replace(' ', '-')}_{mode}"
            image = out / f"{stem}.png"
            if mode == "error-aware-analytic":
                options = BuildOptions(
                    mode="error-aware", odometry_error=load_odometry_error(Path(args[0])),
                    error_samples=0,
                )  # fmt: skip
                write_map(image, build_map(selected, robot, options).map, mode="scale", force=True)
            else:
                gridmap(
                    "build", str(path), "-o", str(image), "--map-mode", "scale", "--force",
                    "--quiet", *window(part.start_s, part.end_s), *args,
                )  # fmt: skip
            pmap = load_probability_map(image.with_suffix(".yaml"))
            e = evaluate_map(pmap, truth.walls, truth.spec, region, start, truth.known)
            runs.append(RealRun(name, part.name, mode, e, image.with_suffix(".yaml"), start))
            print(
                f"{name:13s} {part.name:12s} {mode:22s} NLL {e.nll:.4f} Brier {e.brier:.4f} "
                f"ECE {e.ece:.4f} F1 {e.f1:.3f} coverage {e.coverage:.3f}",
                flush=True,
            )
    models = {half: load_odometry_error(p) for half, p in cals.items()}
    return runs, models, truth


def _texts(part: Part) -> tuple[str | None, str | None]:
    return (
        None if part.start_s is None else f"{part.start_s:.3f}",
        None if part.end_s is None else f"{part.end_s:.3f}",
    )


def run_all(
    out: Path, logs: tuple[str, ...] = LOGS, modes: tuple[str, ...] = tuple(MODES)
) -> tuple[list[RealRun], dict[str, dict[str, OdometryError]], dict[str, Truth]]:
    """Every log's runs, the calibration of each half, and each log's reference."""
    out.mkdir(parents=True, exist_ok=True)
    whole = {}
    if "error-aware-other-log" in modes:
        for name in sorted(set(CROSS[n] for n in logs)):
            whole[name] = calibrate(name, out, None, None, "whole")
    cross = {n: whole.get(CROSS[n], Path()) for n in logs}
    runs: list[RealRun] = []
    calibrations: dict[str, dict[str, OdometryError]] = {}
    truths: dict[str, Truth] = {}
    for name in logs:
        r, c, t = run_log(name, out, cross, modes)
        runs += r
        calibrations[name] = c
        truths[name] = t
    return runs, calibrations, truths


def change(runs: list[RealRun], log: str, part: str) -> tuple[float, str] | None:
    """NLL change of the claimed mode against the best drift-blind one, and which that was."""
    pick = {r.mode: r.evaluation.nll for r in runs if (r.log, r.part) == (log, part)}
    blind = {m: pick[m] for m in DRIFT_BLIND if m in pick}
    if CLAIMED not in pick or not blind:
        return None
    best = min(blind, key=lambda m: blind[m])
    return (pick[CLAIMED] - blind[best]) / blind[best], best


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", default=",".join(LOGS))
    parser.add_argument("--modes", default=",".join(MODES))
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "carmen-experiment")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    logs = tuple(n for n in args.logs.split(",") if n)
    runs, _, _ = run_all(args.out, logs, tuple(m for m in args.modes.split(",") if m))
    for log in logs:
        for part in dict.fromkeys(r.part for r in runs if r.log == log):
            c = change(runs, log, part)
            if c is not None and not math.isnan(c[0]):
                print(f"{log} {part}: {100 * c[0]:+.1f} % against {c[1]}")
    print(f"{time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
