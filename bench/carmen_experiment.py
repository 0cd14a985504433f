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
import dataclasses
import gzip
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
from gridmap_cli.poses.calibration import bias_check
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
LOGS = ("intel", "aces", "freiburg-079", "seattle", "acapulco", "belgioioso")
#: The first minutes of a log, where its drift is still small.
FIRST_S = 180.0
#: A log shorter than twice this (seconds) is cut in halves by its records, not by time.
MIN_HALF_S = 1.0
#: Build arguments of each mode; ``{cal}`` is the other half's calibration, ``{perfect}`` a
#: perfect-odometry file (the version line alone), ``{cross}`` another log's calibration.
MODES: dict[str, list[str]] = {
    "standard": ["--mode", "standard"],
    "standard-corrected": ["--odometry-error", "{cal}", "--correct-odometry"],
    "error-aware-perfect": ["--mode", "error-aware", "--odometry-error", "{perfect}"],
    # the claimed mode as users get it: the build's defaults decide what of the file to correct
    "error-aware": ["--mode", "error-aware", "--odometry-error", "{cal}"],
    "error-aware-uncorrected": ["--mode", "error-aware", "--odometry-error", "{cal}",
                                "--no-correct-odometry"],
    "error-aware-other-log": [
        "--mode", "error-aware", "--odometry-error", "{cross}", "--correct-odometry"
    ],
}  # fmt: skip
#: The modes run by default (``--modes`` may name any of :data:`MODES`).
DEFAULT_MODES = ("standard", "standard-corrected", "error-aware-perfect", "error-aware")
#: The claim: error-aware against the best of these drift-blind mappers.
DRIFT_BLIND = ("standard", "standard-corrected", "error-aware-perfect")
CLAIMED = "error-aware"
#: The claim's bounds on the NLL ratio (error-aware / best drift-blind).
EVERY_HALF, MOST_DRIFTING, MEAN = 1.02, 0.88, 0.93
HALVES = ("first half", "second half")
#: The parts mapped with another log's whole calibration (:data:`CROSS`).
OTHER = "other log"
#: The log whose whole-log calibration each log borrows for ``error-aware-other-log``: the next
#: one in :data:`LOGS`, round the list (another robot's calibration).
CROSS = {name: LOGS[(i + 1) % len(LOGS)] for i, name in enumerate(LOGS)}


@dataclass(frozen=True)
class Part:
    """A window of a log (seconds from its start; None = open) and the calibration half."""

    name: str
    start_s: float | None
    end_s: float | None
    calibrated_on: str
    #: The file the part is read from (the log, or a half of it cut by records).
    source: Path = Path()


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
        out += ["--start", f"{start:.6f}"]
    if end is not None:
        out += ["--end", f"{end:.6f}"]
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


def calibrate(
    name: str,
    out: Path,
    start: float | None,
    end: float | None,
    tag: str,
    source: Path | None = None,
) -> Path:
    """``gridmap calibrate`` on ``name``'s log (or ``source``) from ``start`` to ``end``."""
    path = out / f"{name}_calibration_{tag}.yaml"
    gridmap(
        "calibrate", str(source or log_path(name)), "-o", str(path), "--force", "--quiet",
        *window(start, end),
    )  # fmt: skip
    return path


def halves(
    name: str, data: RangeLog, out: Path
) -> dict[str, tuple[Path, float | None, float | None]]:
    """Each half of ``name``'s log: the file to read and its window (seconds). A log whose
    stamps do not advance (Belgioioso's are all one printed value) cannot be cut by time, so
    it is cut by its records into two files instead, at the end of the scan nearest the
    middle, each with the log's header."""
    path = log_path(name)
    total = duration_s(data)
    if total >= 2.0 * MIN_HALF_S:
        mid = 0.5 * total
        return {HALVES[0]: (path, None, mid), HALVES[1]: (path, mid, None)}
    with gzip.open(path, "rt", encoding="utf-8") as f:
        lines = f.readlines()
    head = next(i for i, line in enumerate(lines) if line.startswith(("ODOM", "FLASER")))
    cut = head + (len(lines) - head) // 2
    while cut < len(lines) and not lines[cut - 1].startswith("NEFF"):
        cut += 1
    out.mkdir(parents=True, exist_ok=True)
    files = {}
    for half, body in zip(HALVES, (lines[head:cut], lines[cut:]), strict=True):
        part = out / f"{name}-{half.split()[0]}-half.log"
        part.write_text("".join(lines[:head] + body), encoding="utf-8")
        files[half] = (part, None, None)
    return files


def run_log(
    name: str, out: Path, cross: dict[str, Path], modes: tuple[str, ...]
) -> tuple[list[RealRun], dict[str, OdometryError], Truth]:
    path = log_path(name)
    data = read_log(path)
    robot = robot_from_log(path, data.metadata)
    ref_yaml = reference(name, out)
    truth = load_truth(ref_yaml)
    cut = halves(name, data, out)
    cals = {
        half: calibrate(name, out, start, end, half.split()[0], source)
        for half, (source, start, end) in cut.items()
    }
    parts = [
        Part(half, start, end, HALVES[1 - k], source)
        for k, (half, (source, start, end)) in enumerate(cut.items())
    ]
    if name in cross:
        cals[OTHER] = cross[name]
        parts += [dataclasses.replace(p, name=f"{p.name}, {OTHER}", calibrated_on=OTHER)
                  for p in parts]  # fmt: skip
    if duration_s(data) > 2.0 * FIRST_S:
        parts.append(Part(f"first {FIRST_S / 60:g} min", None, FIRST_S, HALVES[1], path))
    runs = []
    done: dict[tuple[str, str, float | None, float | None], RealRun] = {}
    logs = {path: data}
    for part in parts:
        if part.source not in logs:
            logs[part.source] = read_log(part.source)
        whole = logs[part.source]
        selected = apply_selection(whole, Selection.parse((), *_texts(part)), robot).log
        true_path = selected.require_truth("the experiment scores against the reference")
        region = sensed_region(truth.world, true_path, sensors_for_log(selected, robot))
        start = odometry_frame_in_world(selected)
        drift = odometry_drift_m(selected)
        fill = {"{cal}": cals[part.calibrated_on], "{cross}": cross.get(name, Path()),
                "{perfect}": perfect_file(out)}  # fmt: skip
        for mode in modes:
            # a mode that takes no calibration maps a window the same whatever the part's
            key = (mode, str(part.source), part.start_s, part.end_s)
            if not any("{cal}" in a or "{cross}" in a for a in MODES[mode]) and key in done:
                runs.append(dataclasses.replace(done[key], part=part.name))
                continue
            args = list(MODES[mode])
            for k, value in fill.items():
                args = [a.replace(k, str(value)) for a in args]
            stem = f"{name}_{part.name.replace(' ', '-').replace(',', '')}_{mode}"
            image = out / f"{stem}.png"
            gridmap(
                "build", str(part.source), "-o", str(image), "--map-mode", "scale", "--force",
                "--quiet", *window(part.start_s, part.end_s), *args,
            )  # fmt: skip
            pmap = load_probability_map(image.with_suffix(".yaml"))
            e = evaluate_map(pmap, truth.walls, truth.spec, region, start, truth.known)
            run = RealRun(name, part.name, mode, e, image.with_suffix(".yaml"), start, drift)
            runs.append(run)
            done[key] = run
            print(
                f"{name:13s} {part.name:24s} {mode:22s} NLL {e.nll:.4f} Brier {e.brier:.4f} "
                f"ECE {e.ece:.4f} F1 {e.f1:.3f} coverage {e.coverage:.3f} drift {drift:.1f} m",
                flush=True,
            )
    models = {half: load_odometry_error(cals[half]) for half in HALVES}
    return runs, models, truth


def _texts(part: Part) -> tuple[str | None, str | None]:
    return (
        None if part.start_s is None else f"{part.start_s:.6f}",
        None if part.end_s is None else f"{part.end_s:.6f}",
    )


def run_all(
    out: Path,
    logs: tuple[str, ...] = LOGS,
    modes: tuple[str, ...] = DEFAULT_MODES,
    cross_log: bool = True,
) -> tuple[list[RealRun], dict[str, dict[str, OdometryError]], dict[str, Truth]]:
    """Every log's runs, the calibration of each half, and each log's reference."""
    out.mkdir(parents=True, exist_ok=True)
    whole = {}
    if cross_log:
        for name in sorted(set(CROSS[n] for n in logs)):
            whole[name] = calibrate(name, out, None, None, "whole")
    cross = {n: whole[CROSS[n]] for n in logs if CROSS[n] in whole}
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
    """The claim, measured: a table of the ratio per log and half (each half calibrated on the
    other, then on another log), then one line per bound with met or missed (markdown, what
    docs/experiments.md shows)."""
    logs = list(dict.fromkeys(r.log for r in runs))
    drift = {log: max(r.drift_m for r in runs if r.log == log and r.part in HALVES) for log in logs}
    lines = [
        "| log | half | calibrated on | odometry drift (m) | error-aware NLL | best drift-blind "
        "| its NLL | ratio |",
        "|---|---|---|---|---|---|---|---|",
    ]
    ratios: dict[tuple[str, str], float] = {}
    others: dict[tuple[str, str], float] = {}
    for log in logs:
        for part in (*HALVES, *(f"{h}, {OTHER}" for h in HALVES)):
            got = ratio(runs, log, part)
            if got is None:
                continue
            value, best = got
            own = part in HALVES
            (ratios if own else others)[log, part] = value
            nll = {r.mode: r for r in runs if (r.log, r.part) == (log, part)}
            source = HALVES[1 - HALVES.index(part)] if own else f"{CROSS[log]} (whole)"
            flag = "" if value <= EVERY_HALF else " **over**"
            lines.append(
                f"| {log} | {part.split(',')[0]} | {source} | {nll[best].drift_m:.1f} | "
                f"{nll[CLAIMED].evaluation.nll:.3f} | {best} | {nll[best].evaluation.nll:.3f} | "
                f"{value:.3f}{flag} |"
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
        f"- <= {EVERY_HALF:.2f}x on every half calibrated on the other: worst {worst:.3f}, "
        f"{verdict(worst <= EVERY_HALF)}",
        f"- <= {MOST_DRIFTING:.2f}x on the most drifting log ({most}, its odometry "
        f"{drift[most]:.0f} m off): worst half {most_ratio:.3f}, "
        f"{verdict(most_ratio <= MOST_DRIFTING)}",
        f"- mean <= {MEAN:.2f}: {mean:.3f}, {verdict(mean <= MEAN)}",
    ]
    if others:
        worst_other = max(others.values())
        lines.append(
            f"- another log's calibration, <= {EVERY_HALF:.2f}x on every half: worst "
            f"{worst_other:.3f}, {verdict(worst_other <= EVERY_HALF)} (mean "
            f"{sum(others.values()) / len(others):.3f})"
        )
    return lines


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", default=",".join(LOGS))
    parser.add_argument(
        "--modes", default=",".join(DEFAULT_MODES), help=f"any of {', '.join(MODES)}"
    )
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "carmen-experiment")
    parser.add_argument(
        "--sigma",
        type=float,
        default=bias_check.SIGMA,
        help="standard errors of the bias checks (the product's 2): is the table on a knife edge?",
    )
    parser.add_argument(
        "--no-other-log", action="store_true", help="skip the parts mapped with another log's"
    )
    args = parser.parse_args(argv)
    bias_check.SIGMA = args.sigma  # the commands run in this process
    started = time.perf_counter()
    logs = tuple(n for n in args.logs.split(",") if n)
    modes = tuple(m for m in args.modes.split(",") if m)
    runs, _, _ = run_all(args.out, logs, modes, cross_log=not args.no_other_log)
    print("\n".join(claim_lines(runs)))
    print(f"{time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
