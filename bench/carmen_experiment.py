"""The real part of ``make experiment``: the error-aware claim on the CARMEN logs (issue 19).

For each corrected log of ``../shared/data/carmen`` (Intel, ACES, Freiburg 079):

* the **reference map** is built from the corrected (SLAM) poses, ``gridmap build --pose global
  --mode error-aware`` with a perfect-odometry file, trinary: the standard map of the corrected
  poses (with no pose error the error-aware mode is the standard one);
* the log is cut in two halves by time; the odometry error is calibrated (``gridmap calibrate``,
  the robust fit) on one half and the maps of the *other* half are built with it, so no scored
  half is ever calibrated on; the first minutes of the log (where the drift is still small) are
  built with the second half's calibration;
* every map is built from the robot's own odometry in scale mode and scored as ``gridmap
  evaluate --log --start --end`` scores it: over the reference's known cells that the window's
  corrected path could have sensed, the map placed by the window's first reference pose.

The claim (issue 19): the error-aware map (:data:`CLAIMED`: the calibrated biases corrected, the
random part spread) against the best of the drift-blind maps (:data:`DRIFT_BLIND`: standard,
standard with ``--correct-odometry``, error-aware with a perfect-odometry file), per half: NLL
ratio <= 1.02 on every half, <= 0.88 on both halves of the log whose odometry drifts most, mean
<= 0.93.

    .venv/bin/python bench/carmen_experiment.py    # the scores and the claim (make experiment
                                                    # writes them into docs/experiments.md)
    .venv/bin/python bench/carmen_experiment.py --logs aces --modes standard,error-aware
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

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
from gridmap_cli.mapping.selection import Selection, apply_selection
from gridmap_cli.poses.calibration.windows import truth_at_odometry
from gridmap_cli.poses.odometry_error import (
    FORMAT_KEY,
    FORMAT_VERSION,
    OdometryError,
    load_odometry_error,
)
from gridmap_cli.poses.sync import sensors_for_log
from gridmap_cli.readers import read_log
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import robot_from_log

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "carmen"
LOGS = ("intel", "aces", "freiburg-079")
#: The first minutes of a log, where its drift is still small.
FIRST_S = 180.0
#: Build arguments of each mode; ``{cal}`` is the other half's calibration, ``{perfect}`` a
#: perfect-odometry file (the version line alone), ``{cross}`` another log's calibration.
MODES: dict[str, list[str]] = {
    "standard": ["--mode", "standard"],
    "standard-corrected": ["--odometry-error", "{cal}", "--correct-odometry"],
    "error-aware-perfect": ["--mode", "error-aware", "--odometry-error", "{perfect}"],
    "error-aware": ["--mode", "error-aware", "--odometry-error", "{cal}", "--correct-odometry"],
    "error-aware-uncorrected": ["--mode", "error-aware", "--odometry-error", "{cal}",
                                "--no-correct-odometry"],
    "error-aware-other-log": [
        "--mode", "error-aware", "--odometry-error", "{cross}", "--correct-odometry"
    ],
}  # fmt: skip
#: The modes run by default (``--modes`` may name any of :data:`MODES`).
DEFAULT_MODES = ("standard", "standard-corrected", "error-aware-perfect", "error-aware",
                 "error-aware-uncorrected")  # fmt: skip
#: The claim: error-aware against the best of these drift-blind mappers.
DRIFT_BLIND = ("standard", "standard-corrected", "error-aware-perfect")
CLAIMED = "error-aware"
#: The claim's bounds on the NLL ratio (error-aware / best drift-blind).
EVERY_HALF, MOST_DRIFTING, MEAN = 1.02, 0.88, 0.93
HALVES = ("first half", "second half")
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
    #: How far the part's odometry strays from the reference (metres, the largest distance
    #: with the two placed at the part's first pose).
    drift_m: float = math.nan


def gridmap(*args: str) -> None:
    """Run one ``gridmap`` command in-process; a failure stops the experiment. A build names
    no pose source unless it means another: the claim is about maps of the robot's odometry,
    and build's own default would map a laser log with the pose graph."""
    if args and args[0] == "build" and "--pose" not in args:
        args = (*args, "--pose", "odometry")
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


def perfect_file(out: Path) -> Path:
    path = out / "perfect-odometry.yaml"
    path.write_text(f"{FORMAT_KEY}: {FORMAT_VERSION}\n")
    return path


def reference(name: str, out: Path) -> Path:
    image = out / f"{name}_reference.png"
    gridmap(
        "build", str(log_path(name)), "--pose", "global", "-o", str(image), "--force", "--quiet",
        "--mode", "error-aware", "--odometry-error", str(perfect_file(out)),
    )  # fmt: skip
    return image.with_suffix(".yaml")


def odometry_drift_m(log: RangeLog) -> float:
    """The largest distance (metres) between the odometry and the reference over ``log``, the
    odometry placed by the first reference pose."""
    odometry, truth = truth_at_odometry(log)
    if len(truth) == 0:
        return math.nan
    x0, y0, th0 = odometry_frame_in_world(log)
    c, s = math.cos(th0), math.sin(th0)
    x = x0 + c * odometry.x_m - s * odometry.y_m
    y = y0 + s * odometry.x_m + c * odometry.y_m
    return float(np.max(np.hypot(x - truth.x_m, y - truth.y_m)))


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
        drift = odometry_drift_m(selected)
        fill = {"{cal}": cals[part.calibrated_on], "{cross}": cross.get(name, Path()),
                "{perfect}": perfect_file(out)}  # fmt: skip
        for mode in modes:
            args = list(MODES[mode])
            for key, value in fill.items():
                args = [a.replace(key, str(value)) for a in args]
            stem = f"{name}_{part.name.replace(' ', '-')}_{mode}"
            image = out / f"{stem}.png"
            gridmap(
                "build", str(path), "-o", str(image), "--map-mode", "scale", "--force",
                "--quiet", *window(part.start_s, part.end_s), *args,
            )  # fmt: skip
            pmap = load_probability_map(image.with_suffix(".yaml"))
            e = evaluate_map(pmap, truth.walls, truth.spec, region, start, truth.known)
            runs.append(RealRun(name, part.name, mode, e, image.with_suffix(".yaml"), start, drift))
            print(
                f"{name:13s} {part.name:12s} {mode:22s} NLL {e.nll:.4f} Brier {e.brier:.4f} "
                f"ECE {e.ece:.4f} F1 {e.f1:.3f} coverage {e.coverage:.3f} drift {drift:.1f} m",
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
    out: Path, logs: tuple[str, ...] = LOGS, modes: tuple[str, ...] = DEFAULT_MODES
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


def ratio(runs: list[RealRun], log: str, part: str) -> tuple[float, str] | None:
    """NLL of the claimed mode over the best drift-blind one's, and which that was."""
    pick = {r.mode: r.evaluation.nll for r in runs if (r.log, r.part) == (log, part)}
    blind = {m: pick[m] for m in DRIFT_BLIND if m in pick}
    if CLAIMED not in pick or not blind:
        return None
    best = min(blind, key=lambda m: blind[m])
    return pick[CLAIMED] / blind[best], best


def change(runs: list[RealRun], log: str, part: str) -> tuple[float, str] | None:
    """NLL change of the claimed mode against the best drift-blind one (ratio - 1)."""
    r = ratio(runs, log, part)
    return None if r is None else (r[0] - 1.0, r[1])


def claim_lines(runs: list[RealRun]) -> list[str]:
    """The claim, measured: a table of the ratio per log and half, then one line per bound
    with met or missed (markdown, what docs/experiments.md shows)."""
    logs = list(dict.fromkeys(r.log for r in runs))
    drift = {log: max(r.drift_m for r in runs if r.log == log and r.part in HALVES) for log in logs}
    lines = [
        "| log | half | odometry drift (m) | error-aware NLL | best drift-blind | its NLL "
        "| ratio |",
        "|---|---|---|---|---|---|---|",
    ]
    ratios: dict[tuple[str, str], float] = {}
    for log in logs:
        for part in HALVES:
            got = ratio(runs, log, part)
            if got is None:
                continue
            value, best = got
            ratios[log, part] = value
            nll = {r.mode: r for r in runs if (r.log, r.part) == (log, part)}
            lines.append(
                f"| {log} | {part} | {nll[best].drift_m:.1f} | "
                f"{nll[CLAIMED].evaluation.nll:.3f} | {best} | {nll[best].evaluation.nll:.3f} | "
                f"{value:.3f} |"
            )
    if not ratios:
        return lines
    worst = max(ratios.values())
    most = max((log for log in logs if any(k[0] == log for k in ratios)), key=drift.__getitem__)
    most_ratio = max(v for k, v in ratios.items() if k[0] == most)
    mean = sum(ratios.values()) / len(ratios)

    def verdict(ok: bool) -> str:
        return "met" if ok else "missed"

    lines += [
        "",
        f"- <= {EVERY_HALF:.2f}x on every half: worst {worst:.3f}, {verdict(worst <= EVERY_HALF)}",
        f"- <= {MOST_DRIFTING:.2f}x on the most drifting log ({most}, its odometry "
        f"{drift[most]:.0f} m off): worst half {most_ratio:.3f}, "
        f"{verdict(most_ratio <= MOST_DRIFTING)}",
        f"- mean <= {MEAN:.2f}: {mean:.3f}, {verdict(mean <= MEAN)}",
    ]
    return lines


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", default=",".join(LOGS))
    parser.add_argument(
        "--modes", default=",".join(DEFAULT_MODES), help=f"any of {', '.join(MODES)}"
    )
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "carmen-experiment")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    logs = tuple(n for n in args.logs.split(",") if n)
    runs, _, _ = run_all(args.out, logs, tuple(m for m in args.modes.split(",") if m))
    print("\n".join(claim_lines(runs)))
    print(f"{time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
