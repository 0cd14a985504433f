"""The mapping experiment of issue 3: every mapping mode against ground truth, per world and drift.

For each world of samples/ (with its path) and each odometry drift level, simulates a few runs
(one per seed), builds one map per mapping mode in scale mode, scores each map with
``gridmap evaluate``'s functions over the cells the run's sensors could have sensed, and writes
``docs/experiments.md`` (mean and spread over seeds) and a figure of maps side by side.

Odometry-error coefficients are calibrated once per drift level with ``gridmap calibrate`` on a
separate, longer run (its own seed), never on the runs that are reported; a mode's build
arguments may refer to that file as ``{calibration}``.

Every step goes through the ``gridmap`` commands, in-process, as a user would type them, so a
mode is just a list of ``gridmap build`` arguments. To add one, add an entry to ``MODE_ARGS``
(or pass ``--modes``):

    MODE_ARGS["name"] = ["--mode", "error-aware", "--odometry-error", "{calibration}"]

    .venv/bin/python bench/experiment.py                  # or: make experiment
    .venv/bin/python bench/experiment.py --modes standard --seeds 1 --drifts 1 --no-doc
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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
from gridmap_cli.evaluation.plot import map_rgb
from gridmap_cli.poses.odometry_error import load_odometry_error
from gridmap_cli.poses.sync import sensors_for_log
from gridmap_cli.readers import read_log
from gridmap_cli.robot import load_robot
from gridmap_cli.sim.odometry import OdometryErrorModel

# the real part lives beside this script, which runs as a file (make experiment) or is loaded
# from its path (tests), never as a package
sys.path.insert(0, str(Path(__file__).resolve().parent))
import carmen_experiment as carmen

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"
WORLDS = ("corridor_loop", "office", "hall")
DRIFTS = (0.0, 1.0, 2.0)
SEEDS = (21, 22, 23)
#: Seed of the calibration run of every drift level: none of the reported runs uses it.
CALIBRATION_SEED = 20
#: The calibration run: the corridor loop, long enough for many corners (turn terms need them).
CALIBRATION_WORLD = "corridor_loop"
CALIBRATION_DURATION_S = 1200.0
ROBOT = "p3at"

#: ``gridmap build`` arguments of each mapping mode; ``{calibration}`` is replaced by the
#: odometry-error file of the run's drift level. Modes not listed run as ``--mode NAME``.
MODE_ARGS: dict[str, list[str]] = {
    "standard": ["--mode", "standard"],
    # the error-aware mode with every f and g coefficient 0: no pose error, so the standard
    # models' map (the row checks that the mode adds nothing without the odometry terms)
    "error-aware-f0g0": ["--mode", "error-aware", "--odometry-coefficient", "range_m_per_m=0"],
    # the calibrated biases taken out of the track, then the standard map: drift-blind, but
    # with what calibration knows
    "standard-corrected": ["--odometry-error", "{calibration}", "--correct-odometry"],
    # the claimed mode as users get it: the biases corrected (the default), the random part spread
    "error-aware": ["--mode", "error-aware", "--odometry-error", "{calibration}"],
    # the biases spread as constant errors instead of corrected
    "error-aware-uncorrected": [
        "--mode", "error-aware", "--odometry-error", "{calibration}", "--no-correct-odometry"
    ],
}  # fmt: skip
#: The claim of issue 3: error-aware against standard.
CLAIM = ("error-aware", "standard")
#: The drift-blind map that knows the calibrated biases, beside the claim.
CORRECTED = "standard-corrected"
SCORES = ("nll", "brier", "ece", "f1", "coverage")


def mode_args(mode: str, calibration: Path) -> list[str]:
    args = MODE_ARGS.get(mode, ["--mode", mode])
    return [a.replace("{calibration}", str(calibration)) for a in args]


def gridmap(*args: str) -> None:
    """Run one ``gridmap`` command in-process; a failure stops the experiment."""
    try:
        cli.main(args=list(args), prog_name="gridmap", standalone_mode=False)
    except Exception as exc:
        raise SystemExit(f"gridmap {' '.join(args)}: {exc}") from exc


@dataclass(frozen=True)
class Run:
    """One map scored: ``evaluation.p_world`` is the map on the world grid, placed by
    ``map_to_world`` (the run's odometry frame in the world)."""

    world: str
    drift: float
    seed: int
    mode: str
    evaluation: Evaluation
    map_yaml: Path
    map_to_world: Pose


def drift_name(drift: float) -> str:
    return f"{drift:g}"


def simulate(world: str, out: Path, seed: int, drift: float, duration: float | None) -> Path:
    extra = ["--duration", str(duration)] if duration else []
    gridmap(
        "simulate", str(SAMPLES / "worlds" / f"{world}.yaml"),
        str(SAMPLES / "paths" / f"{world}.yaml"), "-o", str(out), "--robot", ROBOT,
        "--seed", str(seed), "--drift", str(drift), "--force", "--quiet", *extra,
    )  # fmt: skip
    return out


def calibrate(out: Path, drift: float) -> Path:
    """Calibration file for ``drift``, from its own run (seed :data:`CALIBRATION_SEED`)."""
    log = simulate(
        CALIBRATION_WORLD,
        out / f"calibration_drift{drift_name(drift)}.csv",
        CALIBRATION_SEED,
        drift,
        CALIBRATION_DURATION_S,
    )
    yaml_path = log.with_suffix(".yaml")
    gridmap("calibrate", str(log), "-o", str(yaml_path), "--force")
    return yaml_path


def load_truths(worlds: tuple[str, ...]) -> dict[str, Truth]:
    """Each world's ground truth, by name, in the order given."""
    return {w: load_truth(SAMPLES / "worlds" / f"{w}.yaml") for w in worlds}


def run_all(
    out: Path,
    truths: dict[str, Truth],
    drifts: tuple[float, ...],
    seeds: tuple[int, ...],
    modes: tuple[str, ...],
) -> tuple[list[Run], dict[str, Any]]:
    out.mkdir(parents=True, exist_ok=True)
    calibrations = {d: calibrate(out, d) for d in drifts}
    robot = load_robot(ROBOT)
    runs: list[Run] = []
    for world, truth in truths.items():
        for drift in drifts:
            for seed in seeds:
                stem = f"{world}_drift{drift_name(drift)}_seed{seed}"
                log_path = simulate(world, out / f"{stem}.csv", seed, drift, None)
                log = read_log(log_path)
                assert log.truth is not None
                # the region and the frame come from the log alone: every mode is scored on
                # the same cells
                region = sensed_region(truth.world, log.truth, sensors_for_log(log, robot))
                start = odometry_frame_in_world(log)
                for mode in modes:
                    image = out / f"{stem}_{mode}.png"
                    gridmap(
                        "build", str(log_path), "-o", str(image), "--robot", ROBOT,
                        "--map-mode", "scale", "--force", "--quiet",
                        *mode_args(mode, calibrations[drift]),
                    )  # fmt: skip
                    pmap = load_probability_map(image.with_suffix(".yaml"))
                    e = evaluate_map(pmap, truth.walls, truth.spec, region, start)
                    runs.append(Run(world, drift, seed, mode, e, image.with_suffix(".yaml"), start))
                    print(
                        f"{stem} {mode:12s} NLL {e.nll:.4f} Brier {e.brier:.4f} "
                        f"ECE {e.ece:.4f} F1 {e.f1:.3f} coverage {e.coverage:.3f}",
                        flush=True,
                    )
    cal = {drift_name(d): load_odometry_error(p).as_dict() for d, p in calibrations.items()}
    return runs, cal


def mean_sd(values: list[float]) -> str:
    values = [v for v in values if not math.isnan(v)]
    if not values:
        return "n/a"
    if len(values) == 1:
        return f"{values[0]:.3f}"
    return f"{statistics.fmean(values):.3f} ± {statistics.stdev(values):.3f}"


def figure(
    runs: list[Run], truths: dict[str, Truth], drifts: tuple[float, ...], path: Path
) -> None:
    """Maps of the first seed on the world grid, true walls in red: rows world x mode,
    columns drift levels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    seed = min(r.seed for r in runs)
    modes = list(dict.fromkeys(r.mode for r in runs))
    rows = [(w, m) for w in truths for m in modes]
    fig, axes = plt.subplots(
        len(rows), len(drifts), figsize=(3.6 * len(drifts), 2.6 * len(rows)), squeeze=False
    )
    for i, (world, mode) in enumerate(rows):
        walls = truths[world].walls
        for j, drift in enumerate(drifts):
            ax = axes[i][j]
            run = next(
                r for r in runs if (r.world, r.mode, r.drift, r.seed) == (world, mode, drift, seed)
            )
            rgb = map_rgb(run.evaluation.p_world)
            rgb[walls] = 0.5 * rgb[walls] + 0.5 * np.array([0.95, 0.1, 0.1])
            ax.imshow(rgb, origin="lower", interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(
                f"{world}, {mode}, drift {drift_name(drift)}\nNLL {run.evaluation.nll:.3f}",
                fontsize=8,
            )
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)


def relative_change(runs: list[Run], world: str, drift: float, mode: str, base: str) -> list[float]:
    """Per seed, (NLL of ``mode`` - NLL of ``base``) / NLL of ``base``."""
    out = []
    for seed in sorted({r.seed for r in runs}):
        pick = {
            r.mode: r.evaluation.nll
            for r in runs
            if (r.world, r.drift, r.seed) == (world, drift, seed)
        }
        if mode in pick and base in pick:
            out.append((pick[mode] - pick[base]) / pick[base])
    return out


def claim_lines(runs: list[Run], worlds: tuple[str, ...], drifts: tuple[float, ...]) -> list[str]:
    """The claim of issue 3 checked run by run: NLL change of error-aware against standard."""
    mode, base = CLAIM
    modes = {r.mode for r in runs}
    if mode not in modes or base not in modes:
        return []
    lines = [
        "",
        "## The claim",
        "",
        f"Change of NLL of `{mode}` against `{base}` on the same run, per seed (negative = "
        f"{mode} better). The claim: at least 15 % lower at drift 1 and 2, at most 2 % higher at "
        "drift 0.",
        "",
        "| world | drift | mean change | per seed | claim met on every seed | against "
        f"`{CORRECTED}`, mean |",
        "|---|---|---|---|---|---|",
    ]
    for world in worlds:
        for drift in drifts:
            ch = relative_change(runs, world, drift, mode, base)
            if not ch:
                continue
            ok = all(c <= 0.02 for c in ch) if drift == 0 else all(c <= -0.15 for c in ch)
            blind = relative_change(runs, world, drift, mode, CORRECTED)
            lines.append(
                f"| {world} | {drift_name(drift)} | {100 * statistics.fmean(ch):+.1f} % | "
                + ", ".join(f"{100 * c:+.1f} %" for c in ch)
                + f" | {'yes' if ok else 'no'} | "
                + (f"{100 * statistics.fmean(blind):+.1f} %" if blind else "n/a")
                + " |"
            )
    ablation = "error-aware-f0g0"
    if ablation in modes:
        lines += [
            "",
            f"What the odometry terms add on their own: NLL of `{mode}` against `{ablation}` "
            "(same model with f = g = 0), mean over seeds:",
            "",
            "| world | " + " | ".join(f"drift {drift_name(d)}" for d in drifts) + " |",
            "|---|" + "---|" * len(drifts),
        ]
        for world in worlds:
            cells = []
            for drift in drifts:
                ch = relative_change(runs, world, drift, mode, ablation)
                cells.append(f"{100 * statistics.fmean(ch):+.1f} %" if ch else "n/a")
            lines.append(f"| {world} | " + " | ".join(cells) + " |")
    return lines


def _machine() -> str:
    """What this run ran on, in words: cores and processor, read off the machine itself."""
    cores = os.cpu_count() or 0
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"a {cores}-core machine ({model})"


def write_doc(
    runs: list[Run],
    calibration: dict[str, Any],
    args: argparse.Namespace,
    seconds: float,
    image: Path | None,
    counts: tuple[str, ...] = (),
) -> str:
    modes = list(dict.fromkeys(r.mode for r in runs))
    lines = [
        "# Experiments: map quality against ground truth",
        "",
        "Generated by `make experiment` (`bench/experiment.py`); do not edit by hand.",
        "",
        f"Worlds {', '.join(args.worlds)} from `samples/worlds/` with their paths from "
        f"`samples/paths/` (one pass each), robot `{ROBOT}`, drift levels "
        f"{', '.join(drift_name(d) for d in args.drifts)}, seeds "
        f"{', '.join(str(s) for s in args.seeds)}; modes {', '.join(modes)}. Every map is built "
        "with `gridmap build --map-mode scale` (probabilities kept) and scored as "
        "`gridmap evaluate --log` scores it ([evaluation.md](evaluation.md)): over the world "
        "cells the run's sonars could have sensed from the true path, the same cells for every "
        "mode. NLL in nats per cell. Each cell of the tables is the mean ± the standard "
        "deviation over the seeds.",
        "",
        f"Odometry-error coefficients were calibrated once per drift level with `gridmap "
        f"calibrate` on a separate run ({CALIBRATION_WORLD}, {CALIBRATION_DURATION_S:g} s, seed "
        f"{CALIBRATION_SEED}), never on a reported run:",
        "",
        "| drift | range_m_per_m | range_m_per_sqrt_m | bearing_rad_per_rad | "
        "bearing_rad_per_sqrt_rad | heading_drift_rad_per_m |",
        "|---|---|---|---|---|---|",
    ]
    for d, c in calibration.items():
        lines.append(
            f"| {d} | {c['range_m_per_m']:.4f} | {c['range_m_per_sqrt_m']:.4f} | "
            f"{c['bearing_rad_per_rad']:.4f} | {c['bearing_rad_per_sqrt_rad']:.4f} | "
            f"{c['heading_drift_rad_per_m']:.5f} |"
        )
    # the simulator's drift-1 terms, in the order of the table's columns
    sim = OdometryErrorModel()
    drift1 = (
        sim.scale_error,
        sim.sigma_dist_per_sqrt_m,
        sim.turn_scale_error,
        sim.sigma_turn_per_sqrt_rad,
        sim.heading_drift_rad_per_m,
    )
    lines += [
        "",
        f"(The simulator's drift-1 errors: {', '.join(f'{v:.3g}' for v in drift1)}; drift 2 "
        "doubles them.)",
    ]
    lines += claim_lines(runs, args.worlds, args.drifts)
    for world in args.worlds:
        lines += ["", f"## {world}", ""]
        lines.append("| drift | mode | NLL | Brier | ECE | F1 | coverage |")
        lines.append("|---|---|---|---|---|---|---|")
        for drift in args.drifts:
            for mode in modes:
                sel = [
                    r.evaluation for r in runs if (r.world, r.drift, r.mode) == (world, drift, mode)
                ]
                cells = [mean_sd([getattr(e, s) for e in sel]) for s in SCORES]
                lines.append(f"| {drift_name(drift)} | {mode} | " + " | ".join(cells) + " |")
    if image is not None:
        rel = image.relative_to(ROOT / "docs")
        lines += [
            "",
            "## Maps",
            "",
            f"Seed {min(args.seeds)} of each world and drift, every mode, drawn on the world grid "
            "(grey = 1 - p, unknown pale blue) with the true walls in red, the map placed by the "
            "run's first true pose:",
            "",
            f"![maps side by side]({rel})",
        ]
    lines += [
        "",
        f"This run took {seconds:.0f} s on {_machine()} ("
        + ", ".join([f"{len(runs)} simulated maps", *counts])
        + ").",
        "",
    ]
    return "\n".join(lines)


def carmen_figure(runs: list[carmen.RealRun], truths: dict[str, Truth], path: Path) -> None:
    """Per log (rows): the reference map, then each mode's map of the second half (calibrated
    on the first), on the reference's grid."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    logs = list(truths)
    modes = list(dict.fromkeys(r.mode for r in runs))
    fig, axes = plt.subplots(
        len(logs), len(modes) + 1, figsize=(3.4 * (len(modes) + 1), 3.4 * len(logs)), squeeze=False
    )
    for i, log in enumerate(logs):
        t = truths[log]
        ref = np.where(t.known, np.where(t.walls, 1.0, 0.0), np.nan)
        axes[i][0].imshow(map_rgb(ref), origin="lower", interpolation="nearest")
        axes[i][0].set_title(f"{log}: reference (corrected poses)", fontsize=8)
        for j, mode in enumerate(modes):
            run = next(r for r in runs if (r.log, r.part, r.mode) == (log, "second half", mode))
            rgb = map_rgb(run.evaluation.p_world)
            rgb[t.walls] = 0.5 * rgb[t.walls] + 0.5 * np.array([0.95, 0.1, 0.1])
            ax = axes[i][j + 1]
            ax.imshow(rgb, origin="lower", interpolation="nearest")
            ax.set_title(f"{log}, second half, {mode}\nNLL {run.evaluation.nll:.3f}", fontsize=8)
        for ax in axes[i]:
            ax.set_xticks([])
            ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(path, dpi=70)
    plt.close(fig)


def carmen_lines(
    runs: list[carmen.RealRun], cal: dict[str, dict[str, Any]], image: Path
) -> list[str]:
    """The real part of docs/experiments.md: the claim per log and part, every score, the
    calibrations of each half, the figure."""
    lines = [
        "",
        "## Real logs (CARMEN): the error-aware claim (issues 19 and 29)",
        "",
        "`bench/carmen_experiment.py`, run by `make experiment`. Logs: the six corrected CARMEN "
        "logs of `../shared/data/carmen` (Intel, ACES, Freiburg 079, Seattle, Acapulco, "
        "Belgioioso), each cut in two halves by time (Belgioioso, whose stamps do not advance, by "
        "its records). The odometry error is calibrated (`gridmap calibrate`: the robust fit of "
        "docs/odometry-error.md, which writes only the biases that hold across the calibration "
        "span) on one half and used on the *other* half, both ways; then each half is mapped "
        "with another log's whole calibration (`calibrated on`: the next log in the list, "
        "another robot); the first 3 minutes use the second half's calibration. Modes: "
        "`standard`; `standard-corrected` (`--odometry-error --correct-odometry`: the written "
        "biases taken out of the track); `error-aware-perfect` (a perfect-odometry file: the "
        "standard map again); `error-aware` (the claimed mode as users get it, its defaults: "
        "the written biases corrected, the file checked against the log's own laser, the random "
        "part spread). The reference map is built from the corrected (SLAM) poses, trinary; the "
        "maps from the robot's own odometry, scale mode, scored over the reference's known cells "
        "that the part's corrected path could have sensed, placed by the part's first reference "
        "pose. The reference is a SLAM map, not truth. Odometry drift: the largest distance "
        "between the odometry and the reference over the half.",
        "",
        "The claim: `error-aware` NLL against the best drift-blind map (`standard`, "
        "`standard-corrected`, `error-aware-perfect`) <= 1.02x on every half, <= 0.88x on the "
        "most drifting log, mean <= 0.93.",
        "",
        *carmen.claim_lines(runs),
    ]
    lines += [
        "",
        "| log | part | mode | NLL | Brier | ECE | F1 | coverage |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        e = r.evaluation
        f1 = "n/a" if math.isnan(e.f1) else f"{e.f1:.3f}"
        lines.append(
            f"| {r.log} | {r.part} | {r.mode} | {e.nll:.3f} | {e.brier:.3f} | {e.ece:.3f} | "
            f"{f1} | {e.coverage:.3f} |"
        )
    lines += [
        "",
        "Calibration of each half (`gridmap calibrate --start/--end`) as written, the other "
        "half's maps use it (a bias whose halves disagree by more than 2 standard errors, or "
        "that does not stand 2 standard errors from 0, is written as 0):",
        "",
        "| log | half | distance_scale_bias | turn_scale_bias | heading_drift_bias_rad_per_m | "
        "range_m_per_sqrt_m | bearing_rad_per_sqrt_rad | heading_rad_per_sqrt_m |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for log, halves in cal.items():
        for half, m in halves.items():
            lines.append(
                f"| {log} | {half} | {m.distance_scale_bias:+.4f} | {m.turn_scale_bias:+.4f} | "
                f"{m.heading_drift_bias_rad_per_m:+.5f} | {m.range_m_per_sqrt_m:.4f} | "
                f"{m.bearing_rad_per_sqrt_rad:.4f} | {m.heading_rad_per_sqrt_m:.4f} |"
            )
    rel = image.relative_to(ROOT / "docs")
    lines += [
        "",
        "Second halves, reference first, true (reference) walls in red:",
        "",
        f"![CARMEN maps side by side]({rel})",
    ]
    return lines


def scan_matching() -> tuple[float, list[str]]:
    """Run ``bench/scan_match.py`` (it writes docs/scan-matching-results.md and its figure) on
    one core, as its timings are stated, in its own process; its seconds and the lines that
    point to it."""
    started = time.perf_counter()
    command = [sys.executable, str(Path(__file__).resolve().parent / "scan_match.py")]
    taskset = shutil.which("taskset")
    if taskset is not None:
        command = [taskset, "-c", "0", *command]
    subprocess.run(command, check=True, cwd=ROOT)
    # then the SLAM benchmark's relations table, into the same page
    subprocess.run([*command[:-1], command[-1].replace("scan_match.py", "slam_relations.py")],
                   check=True, cwd=ROOT)  # fmt: skip
    # then every shared real log, two at a time (one per core): its tables go into the same page
    real = [sys.executable, str(Path(__file__).resolve().parent / "real_logs.py"), "--jobs", "2"]
    subprocess.run(real, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    seconds = time.perf_counter() - started
    return seconds, [
        "",
        "## Scan matching on the real logs",
        "",
        "`bench/scan_match.py` and `bench/slam_relations.py`, run by `make experiment` on one "
        "core: odometry, scan-matched and reference tracks and their maps side by side on the "
        "same CARMEN logs, and the odometry, scan-matched and slam tracks scored on the SLAM "
        "benchmark's relations beside the published figures, in "
        f"[scan-matching-results.md](scan-matching-results.md) ({seconds:.0f} s of this run), "
        "with `bench/real_logs.py`'s table of every shared real log: the benchmark's raw logs on "
        "their relations and six corrected CARMEN logs against their corrected poses.",
    ]


REAL_HEADING = "## Real logs (CARMEN)"


def real_only(doc: Path, image: Path, out: Path) -> None:
    """Run the real part of the experiment and replace the doc's real-log sections with it; the
    simulated sections above them are kept as the last full run wrote them, and the closing line
    says which part this run made."""
    kept = doc.read_text().split("\n" + REAL_HEADING, 1)[0].rstrip("\n")
    started = time.perf_counter()
    real_runs, real_cal, real_truths = carmen.run_all(out / "carmen")
    real_image = image.with_name("experiments-carmen.png")
    carmen_figure(real_runs, real_truths, real_image)
    lines = carmen_lines(real_runs, real_cal, real_image)
    scan_seconds, scan_lines = scan_matching()
    seconds = time.perf_counter() - started
    lines += [
        *scan_lines,
        "",
        f"The real-log sections were regenerated alone (`bench/experiment.py --real-only`) in "
        f"{seconds:.0f} s on {_machine()} ({len(real_runs) + len(real_truths)} CARMEN maps, "
        f"references included, {scan_seconds:.0f} s of scan matching); the simulated sections "
        "above are from the last full `make experiment`.",
        "",
    ]
    doc.write_text(kept + "\n" + "\n".join(lines))
    print(f"wrote the real-log sections of {doc} in {seconds:.0f} s", file=sys.stderr)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modes", default=",".join(MODE_ARGS), help="comma-separated")
    parser.add_argument("--worlds", default=",".join(WORLDS), help="comma-separated")
    parser.add_argument("--drifts", default=",".join(drift_name(d) for d in DRIFTS))
    parser.add_argument("--seeds", default=",".join(str(s) for s in SEEDS))
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "experiment")
    parser.add_argument("--doc", type=Path, default=ROOT / "docs" / "experiments.md")
    parser.add_argument("--image", type=Path, default=ROOT / "docs" / "images" / "experiments.png")
    parser.add_argument("--no-doc", action="store_true", help="print the scores only")
    parser.add_argument("--no-real", action="store_true", help="skip the CARMEN logs")
    parser.add_argument(
        "--no-scan-match", action="store_true", help="skip bench/scan_match.py on the CARMEN logs"
    )
    parser.add_argument(
        "--real-only",
        action="store_true",
        help="regenerate the real-log sections of the doc alone, keeping its simulated sections "
        "(for a change that cannot reach the simulator's sonar runs, such as pose correction)",
    )
    args = parser.parse_args(argv)
    if args.real_only:
        real_only(args.doc, args.image, args.out)
        return
    args.modes = tuple(m for m in args.modes.split(",") if m)
    args.worlds = tuple(w for w in args.worlds.split(",") if w)
    args.drifts = tuple(float(d) for d in args.drifts.split(","))
    args.seeds = tuple(int(s) for s in args.seeds.split(","))
    started = time.perf_counter()
    truths = load_truths(args.worlds)
    runs, calibration = run_all(args.out, truths, args.drifts, args.seeds, args.modes)
    (args.out / "results.json").write_text(
        json.dumps(
            [
                {"world": r.world, "drift": r.drift, "seed": r.seed, "mode": r.mode,
                 "map": str(r.map_yaml), "map_to_world": list(r.map_to_world),
                 **r.evaluation.as_dict()}
                for r in runs
            ],
            indent=1,
            default=lambda v: None,
        ).replace("NaN", "null")
    )  # fmt: skip
    real_lines: list[str] = []
    real_maps = 0
    if not args.no_real and carmen.DATA.is_dir():
        real_runs, real_cal, real_truths = carmen.run_all(args.out / "carmen")
        # the scored maps and each log's reference map
        real_maps = len(real_runs) + len(real_truths)
        if not args.no_doc:
            real_image = args.image.with_name("experiments-carmen.png")
            carmen_figure(real_runs, real_truths, real_image)
            real_lines = carmen_lines(real_runs, real_cal, real_image)
    if args.no_doc:
        return
    counts = [f"{real_maps} CARMEN maps, references included"] if real_maps else []
    if not args.no_real and not args.no_scan_match and carmen.DATA.is_dir():
        scan_seconds, scan_lines = scan_matching()
        real_lines += scan_lines
        counts.append(f"{scan_seconds:.0f} s of scan matching")
    figure(runs, truths, args.drifts, args.image)
    seconds = time.perf_counter() - started
    text = write_doc(runs, calibration, args, seconds, args.image, tuple(counts))
    args.doc.write_text(
        text.rstrip("\n").rsplit("\n", 1)[0]
        + "\n"
        + "\n".join(real_lines)
        + "\n\n"
        + text.rstrip("\n").rsplit("\n", 1)[1]
        + "\n"
    )
    print(f"wrote {args.doc} and {args.image} in {seconds:.0f} s", file=sys.stderr)
    if not args.no_real and not args.no_scan_match and carmen.DATA.is_dir():
        # last on stdout: the table a change to mapping or pose correction is judged by
        import real_logs

        kept = real_logs.kept_section(real_logs.DOC)
        if kept is not None:
            print("\n".join(kept.splitlines()[1:-1]))


if __name__ == "__main__":
    main()
