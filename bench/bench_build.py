"""Mapping throughput and memory, whole process, one table: `make bench`.

Simulates (once, cached in bench/.cache/) a Pioneer 3-AT driving laps of the bundled corridor
loop: 16 sonars at 10 Hz, one hour = 576,000 readings, and eight hours; converts the hour to
every input format (ARIA .2d, JSON MCAP, ROS 2 MCAP, ROS 1 bag); simulates a laser-only robot
for about 576,000 laser rays; cuts a 100-reading log. Then times the installed ``gridmap build``
on each, pinned to one core where ``taskset`` exists: wall and CPU seconds, peak RSS (of the
build process alone), readings/s and cell updates/s.

Absolute times depend on the machine and on what else runs on it; the ratio columns do not as
much. They compare CPU seconds (user + system, which other processes on the core do not inflate
as they do wall time): ``vs CSV`` is the row's over the CSV build of the same log and mode (the
ROS targets are <= 1.5x), ``vs ref`` over the reference measured in the same run: the 1-hour CSV
standard build with the numpy reference kernels (:data:`NUMPY_KERNELS`), ``vs std`` an
error-aware row's over the standard build of the same log (issue 19 asks for <= 2x). Rates are
per CPU second too. Freiburg 079 (``../shared/data/carmen``, when present) is timed in both
modes, error-aware with the coefficients ``gridmap calibrate`` fits on it. The SLAM benchmark's
raw Intel bag (``../shared/data/slam-benchmark``, when present; 13,631 scans) is timed with
``--pose slam``: scan matching, loop closure and the map, the whole process on one core
(``--slam`` runs that row alone).

``--repeat N`` runs every command N times and reports the median (default 1: a few minutes).
``--quick`` leaves out the 8-hour log and the ROS 1 bag (their one-off preparation is slow).
OctoMap (``octomap-python``) on the laser rays is timed when importable, and skipped otherwise.
Last, ``bench/bench_json.py`` on the JSON MCAP (one core): JSON messages decoded per second by
msgspec (the reader's way), the standard library's ``json`` and orjson (when importable).

Then memory on large maps (``--memory`` prints this table alone): the laser log at 4 mm cells
(about 30 million cells) in every mode (standard trinary PNG, PGM and scale PNG; error-aware
with its default sampled tracks and with ``--error-samples 0``), and the Freiburg-style real
case, the ACES CARMEN log at 1 cm with its corrected poses, when ``../shared/data/carmen`` is
there: peak RSS, bytes per map cell, and the budget, 12 bytes a cell plus 160 MiB (issue 21).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / "bench" / ".cache"
WORLD = ROOT / "samples" / "worlds" / "corridor_loop.yaml"
PATH = ROOT / "samples" / "paths" / "corridor_loop.yaml"
SEED = 1
HOUR_S = 3600
FREIBURG = ROOT.parent / "shared" / "data" / "carmen" / "freiburg-079-corrected.log.gz"
FREIBURG_ERROR = CACHE / "freiburg-079-odometry.yaml"
#: the SLAM benchmark's raw Intel log (13,631 scans): ``--pose slam`` timed on it, the whole
#: process on one core (issue 28 asks for under 30 s)
INTEL_BAG = ROOT.parent / "shared" / "data" / "slam-benchmark" / "intel.bag"
LASER_S = 318.2  # 3,183 scans of 181 beams: about 576,000 rays
LASER_ROBOT = """\
gridmap-robot: 1
name: lms200-only
sensors:
  - {name: laser1, kind: laser, x_m: 0.16, y_m: 0.0, yaw_deg: 0, first_deg: -90, last_deg: 90,
     samples: 181, max_range_m: 8.0}
"""


#: A row's ``extra_env`` that runs the build on the numpy reference kernels (the bench's own
#: switch: gridmap has none).
NUMPY_KERNELS = {"BENCH_KERNELS": "numpy"}
#: ``python -c`` program: gridmap with the numpy reference kernels.
_NUMPY_GRIDMAP = (
    "import sys\n"
    "from gridmap_cli import extensions\n"
    "extensions.KERNELS = 'numpy'\n"
    "from gridmap_cli.cli import main\n"
    "sys.argv[0] = 'gridmap'\n"
    "main()\n"
)


def gridmap() -> list[str]:
    exe = Path(sys.executable).with_name("gridmap")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "gridmap_cli"]


def one_core(cmd: list[str]) -> list[str]:
    return ["taskset", "-c", "0", *cmd] if shutil.which("taskset") else cmd


# A wrapper process whose only child is the measured command, so that its RUSAGE_CHILDREN
# figures (CPU time, peak RSS) belong to that command alone.
_WRAPPER = (
    "import resource, subprocess, sys\n"
    "code = subprocess.run(sys.argv[1:]).returncode\n"
    "u = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
    "print(u.ru_utime + u.ru_stime, u.ru_maxrss, file=sys.stderr)\n"
    "sys.exit(code)\n"
)


@dataclass(frozen=True)
class Run:
    wall_s: float
    cpu_s: float
    peak_mib: float
    stdout: str


def run_measured(cmd: list[str], env: dict[str, str] | None = None) -> Run:
    """Run cmd once; wall and CPU seconds, peak RSS in MiB and stdout."""
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", _WRAPPER, *cmd],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, **(env or {})},
    )
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"bench: command failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stderr}")
    cpu, peak_kib = proc.stderr.strip().splitlines()[-1].split()
    return Run(wall, float(cpu), int(peak_kib) / 1024, proc.stdout)


def median_run(cmd: list[str], repeat: int, env: dict[str, str] | None = None) -> Run:
    runs = [run_measured(cmd, env) for _ in range(repeat)]
    return Run(
        statistics.median(r.wall_s for r in runs),
        statistics.median(r.cpu_s for r in runs),
        statistics.median(r.peak_mib for r in runs),
        runs[-1].stdout,
    )


def _inputs_digest() -> str:
    """Hash of everything the cached logs depend on, so a changed simulator makes new logs."""
    digest = hashlib.sha256()
    sources = sorted((ROOT / "gridmap_cli" / "sim").glob("*.py"))
    writers = sorted((ROOT / "gridmap_cli" / "writers").glob("*.py"))
    for path in [*sources, *writers, WORLD, PATH, WORLD.with_suffix(".pgm")]:
        digest.update(path.read_bytes())
    digest.update(LASER_ROBOT.encode())
    return digest.hexdigest()[:12]


def _step(what: str, target: Path, make: list[str]) -> Path:
    if not target.exists():
        print(f"  preparing {what} (once; cached at {target.relative_to(ROOT)}) ...", flush=True)
        subprocess.run(make, check=True)
    return target


def simulate(duration_s: float, target: Path, robot: str = "p3at") -> list[str]:
    return [
        *gridmap(), "simulate", str(WORLD), str(PATH), "-o", str(target), "--robot", robot,
        "--duration", str(duration_s), "--seed", str(SEED), "--quiet", "--force",
    ]  # fmt: skip


def prepare(quick: bool) -> dict[str, Path]:
    """Every input, made once per simulator version."""
    CACHE.mkdir(parents=True, exist_ok=True)
    tag = _inputs_digest()
    logs: dict[str, Path] = {}
    hour = logs["csv"] = _step(
        "the 1 h log", CACHE / f"hour_{tag}.csv", simulate(HOUR_S, CACHE / f"hour_{tag}.csv")
    )
    convert = [*gridmap(), "convert", str(hour)]
    logs["aria"] = _step(
        "ARIA .2d", CACHE / f"hour_{tag}.2d", [*convert, str(CACHE / f"hour_{tag}.2d"), "-q"]
    )
    for enc in ("json", "ros2"):
        target = CACHE / f"hour_{tag}_{enc}.mcap"
        logs[f"mcap-{enc}"] = _step(
            f"{enc} MCAP", target, [*convert, str(target), "--encoding", enc, "-q"]
        )
    if not quick:
        bag = CACHE / f"hour_{tag}.bag"
        if not bag.exists():
            print(f"  preparing ROS 1 bag (once; cached at {bag.relative_to(ROOT)}) ...")
            sys.path.insert(0, str(ROOT))
            from tests.readers.bag_helpers import write_bag

            write_bag(logs["mcap-ros2"], bag)
        logs["bag"] = bag
        eight = CACHE / f"eight_{tag}.csv"
        logs["csv-8h"] = _step("the 8 h log", eight, simulate(8 * HOUR_S, eight))
    small = CACHE / f"small_{tag}.csv"
    if not small.exists():
        lines = hour.read_text().splitlines(keepends=True)
        head = [line for line in lines[:20] if line.startswith("#") or line.startswith("time")]
        # 16 sonars a row: 7 rows hold 112 readings, close to the 100 the target names
        small.write_text("".join(head) + "".join(lines[len(head) : len(head) + 7]))
    logs["small"] = small
    robot = CACHE / "lms200-only.yaml"
    robot.write_text(LASER_ROBOT)
    laser = CACHE / f"laser_{tag}.csv"
    logs["laser"] = _step("the laser log", laser, simulate(LASER_S, laser, robot=str(robot)))
    if FREIBURG.exists():  # a real laser log, with its own calibration for error-aware mode
        logs["freiburg"] = FREIBURG
        _step(
            "Freiburg 079's odometry error", FREIBURG_ERROR,
            [*gridmap(), "calibrate", str(FREIBURG), "-o", str(FREIBURG_ERROR), "--quiet"],
        )  # fmt: skip
    return logs


def error_aware_flags() -> list[str]:
    """Error-aware mode with the simulator's drift-1 error as its f and g."""
    from gridmap_cli.sim.odometry import OdometryErrorModel

    drift1 = OdometryErrorModel().as_odometry_error().as_dict()
    flags = ["--mode", "error-aware"]
    for k, v in drift1.items():
        flags += ["--odometry-coefficient", f"{k}={v!r}"]
    return flags


@dataclass(frozen=True)
class Row:
    case: str
    log: str
    mode: str
    extra_env: dict[str, str] | None = None
    csv_peer: str | None = None  # the case whose wall time is this row's "vs CSV" base


def build_cmd(
    log: Path, mode: str, out: Path, robot: str | None, numpy_kernels: bool = False
) -> list[str]:
    program = [sys.executable, "-c", _NUMPY_GRIDMAP] if numpy_kernels else gridmap()
    # the mapping's throughput on the odometry, unless the row times the pose graph (build
    # would pick the graph for a laser log by itself)
    cmd = [*program, "build", str(log), "-o", str(out), "--force", "--quiet", "--json",
           "--pose", "slam" if mode == "slam" else "odometry"]  # fmt: skip
    if robot:
        cmd += ["--robot", robot]
    if mode == "error-aware" and log == FREIBURG:
        cmd += ["--mode", "error-aware", "--odometry-error", str(FREIBURG_ERROR)]
    elif mode == "error-aware":
        cmd += error_aware_flags()
    return one_core(cmd)


def octomap_rays(log: Path) -> float | None:
    """Seconds OctoMap takes to insert the laser log's rays, or None when it is not installed."""
    try:
        import octomap  # type: ignore[import-not-found]  # noqa: F401
    except ImportError:
        return None
    script = (
        "import sys, time, numpy as np, octomap\n"
        "from gridmap_cli.readers import read_log\n"
        "from gridmap_cli.robot import load_robot\n"
        "from gridmap_cli.poses.sync import synchronise\n"
        "log = read_log(__import__('pathlib').Path(sys.argv[1]))\n"
        "r, _ = synchronise(log, load_robot(sys.argv[2]))\n"
        "end_x = r.x_m + r.range_m * np.cos(r.theta_rad)\n"
        "end_y = r.y_m + r.range_m * np.sin(r.theta_rad)\n"
        "tree = octomap.OcTree(0.05)\n"
        "t0 = time.perf_counter()\n"
        "cuts = np.flatnonzero(np.diff(r.stamp_ns)) + 1\n"
        "for lo, hi in zip([0, *cuts], [*cuts, len(r)]):\n"
        "    pts = np.stack([end_x[lo:hi], end_y[lo:hi], np.zeros(hi - lo)], axis=1)\n"
        "    origin = np.array([r.x_m[lo], r.y_m[lo], 0.0])\n"
        "    tree.insertPointCloud(pts, origin, maxrange=8.0, lazy_eval=True)\n"
        "tree.updateInnerOccupancy()\n"
        "print(time.perf_counter() - t0)\n"
    )
    proc = subprocess.run(
        [*one_core([sys.executable, "-c", script]), str(log), str(CACHE / "lms200-only.yaml")],
        capture_output=True,
        text=True,
        check=False,
    )
    if proc.returncode != 0:
        print(f"  OctoMap run failed: {proc.stderr.strip().splitlines()[-1:]}")
        return None
    return float(proc.stdout.strip())


#: Cell size of the large-map cases: the laser log's map at 4 mm is about 30 million cells.
LARGE_RESOLUTION_M = 0.004
#: The memory budget of a build: bytes a map cell, plus a fixed allowance (MiB).
BUDGET_BYTES_PER_CELL = 12
BUDGET_FIXED_MIB = 160
ACES = ROOT.parent / "shared" / "data" / "carmen" / "aces-corrected.log.gz"


def memory_table(laser: Path, laser_robot: str, repeat: int) -> None:
    """Peak RSS and bytes per map cell of large-map builds, against the budget."""
    ea = error_aware_flags()
    cases: list[tuple[str, Path, list[str], str]] = [
        ("laser 4 mm, standard", laser, [], "png"),
        ("laser 4 mm, standard", laser, [], "pgm"),
        ("laser 4 mm, standard, scale", laser, ["--map-mode", "scale"], "png"),
        ("laser 4 mm, error-aware (16 samples)", laser, ea, "png"),
        ("laser 4 mm, error-aware, samples 0", laser, [*ea, "--error-samples", "0"], "png"),
    ]
    robots = {laser: laser_robot}
    if ACES.is_file():
        cases.append(("ACES 1 cm --pose global", ACES, ["--pose", "global"], "png"))
    print(
        f"\nMemory on large maps: peak RSS of the build process, median of {repeat}; budget "
        f"{BUDGET_BYTES_PER_CELL} bytes a cell + {BUDGET_FIXED_MIB} MiB"
    )
    header = (
        f"{'case':38} {'image':5} {'cells':>8} {'peak MiB':>9} {'bytes/cell':>10} "
        f"{'budget MiB':>10}  verdict"
    )
    print(header)
    print("-" * len(header))
    with tempfile.TemporaryDirectory() as tmp:
        for case, log, flags, image in cases:
            resolution = LARGE_RESOLUTION_M if log == laser else 0.01
            out = Path(tmp) / f"large.{image}"
            cmd = [*gridmap(), "build", str(log), "-o", str(out), "--force", "--quiet", "--json",
                   "--resolution", str(resolution), *flags]  # fmt: skip
            if "--pose" not in flags:
                cmd += ["--pose", "odometry"]
            if log in robots:
                cmd += ["--robot", robots[log]]
            run = median_run(one_core(cmd), repeat)
            grid = json.loads(run.stdout)["map"]
            cells = grid["width"] * grid["height"]
            budget = BUDGET_BYTES_PER_CELL * cells / 2**20 + BUDGET_FIXED_MIB
            verdict = "within" if run.peak_mib <= budget else "OVER"
            print(
                f"{case:38} {image:5} {cells / 1e6:7.1f}M {run.peak_mib:9.0f} "
                f"{run.peak_mib * 2**20 / cells:10.1f} {budget:10.0f}  {verdict}",
                flush=True,
            )


def _table(
    rows: list[Row], logs: dict[str, Path], laser_robot: str, repeat: int
) -> tuple[dict[tuple[str, str], float], dict[tuple[str, str], float]]:
    """Time each row's build and print the table; CPU seconds and peak MiB by (log, mode)."""
    pinned = "one core (taskset -c 0)" if shutil.which("taskset") else "unpinned"
    print(
        f"gridmap build, whole process, {pinned}, {os.cpu_count()}-core machine, "
        f"median of {repeat}; 5 cm cells"
    )
    header = (
        f"{'case':34} {'mode':11} {'readings':>9} {'wall s':>7} {'CPU s':>6} {'MiB':>6} "
        f"{'readings/s':>11} {'updates/s':>11} {'vs CSV':>6} {'vs ref':>6} {'vs std':>6}"
        "   (rates and ratios per CPU second)"
    )
    print(header)
    print("-" * len(header))
    cpus: dict[tuple[str, str], float] = {}
    peaks: dict[tuple[str, str], float] = {}
    reference = None
    with tempfile.TemporaryDirectory() as tmp:
        for row in rows:
            env = dict(row.extra_env or {})
            robot = laser_robot if row.log == "laser" else None
            out = Path(tmp) / f"{row.log}_{row.mode}.png"
            numpy_kernels = env.pop("BENCH_KERNELS", None) == "numpy"
            cmd = build_cmd(logs[row.log], row.mode, out, robot, numpy_kernels)
            run = median_run(cmd, repeat, env)
            summary = json.loads(run.stdout)
            readings = summary["readings"]["used"]
            updates = summary["cell_updates"]
            cpu = max(run.cpu_s, 1e-3)
            if reference is None:
                reference = cpu
            if row.extra_env is None:
                cpus[(row.log, row.mode)] = cpu
                peaks[(row.log, row.mode)] = run.peak_mib
            peer = cpus.get((row.csv_peer, row.mode)) if row.csv_peer else None
            vs_csv = f"{cpu / peer:6.2f}" if peer else f"{'':6}"
            # error-aware over the standard build of the same log (issue 19: <= 2x)
            std = cpus.get((row.log, "standard")) if row.mode == "error-aware" else None
            vs_std = f"{cpu / std:6.2f}" if std and row.extra_env is None else f"{'':6}"
            print(
                f"{row.case:34} {row.mode:11} {readings:9,d} {run.wall_s:7.2f} {run.cpu_s:6.2f} "
                f"{run.peak_mib:6.0f} {readings / cpu:11,.0f} {updates / cpu:11,.0f} "
                f"{vs_csv} {cpu / reference:6.2f} {vs_std}",
                flush=True,
            )
    return cpus, peaks


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=1, help="runs per command (median)")
    parser.add_argument("--quick", action="store_true", help="no 8 h log, no ROS 1 bag")
    parser.add_argument("--memory", action="store_true", help="only the large-map memory table")
    parser.add_argument("--slam", action="store_true", help="only --pose slam on the Intel bag")
    args = parser.parse_args()

    if args.memory:
        CACHE.mkdir(parents=True, exist_ok=True)
        robot = CACHE / "lms200-only.yaml"
        robot.write_text(LASER_ROBOT)
        laser = CACHE / f"laser_{_inputs_digest()}.csv"
        _step("the laser log", laser, simulate(LASER_S, laser, robot=str(robot)))
        memory_table(laser, str(robot), args.repeat)
        return
    slam_row = Row("Intel (ROS 1 bag), --pose slam", "intel-slam", "slam")
    if args.slam:
        if not INTEL_BAG.exists():
            sys.exit(f"bench: {INTEL_BAG} is not here")
        _table([slam_row], {"intel-slam": INTEL_BAG}, "", args.repeat)
        return
    logs = prepare(args.quick)
    laser_robot = str(CACHE / "lms200-only.yaml")
    rows = [
        Row("reference: CSV, numpy kernels", "csv", "standard", NUMPY_KERNELS),
    ]
    for mode in ("standard", "error-aware"):
        for fmt in ("csv", "aria", "mcap-json", "mcap-ros2", "bag"):
            if fmt in logs:
                rows.append(Row(fmt, fmt, mode, None, "csv"))
            if fmt == "csv" and mode == "error-aware":
                numpy_path = NUMPY_KERNELS
                rows.append(Row("csv, numpy kernels", "csv", mode, numpy_path, "csv"))
        if "csv-8h" in logs:
            rows.append(Row("CSV, 8 h", "csv-8h", mode))
    rows += [
        Row("CSV, 100 readings", "small", "standard"),
        Row("laser rays, CSV", "laser", "standard"),
        Row("laser rays, numpy kernels", "laser", "standard", NUMPY_KERNELS),
    ]
    if "freiburg" in logs:
        rows += [Row("Freiburg 079 (CARMEN)", "freiburg", m) for m in ("standard", "error-aware")]

    if INTEL_BAG.exists():  # loop closure's cost, on a real log
        logs["intel-slam"] = INTEL_BAG
        rows.append(slam_row)
    cpus, peaks = _table(rows, logs, laser_robot, args.repeat)
    for mode in ("standard", "error-aware"):
        if ("csv-8h", mode) in cpus:
            cpu = cpus[("csv-8h", mode)] / cpus[("csv", mode)]
            peak = peaks[("csv-8h", mode)] / peaks[("csv", mode)]
            print(f"8 h / 1 h, {mode}: CPU {cpu:.1f}x (linear: 8x), peak memory {peak:.2f}x")
    octo = octomap_rays(logs["laser"])
    if octo is None:
        print("OctoMap: skipped (octomap-python is not installed here)")
    else:
        ours = cpus[("laser", "standard")]
        print(f"OctoMap 576k rays: {octo:.2f} s in-process; gridmap whole process {ours:.2f} s CPU")
        print(f"  OctoMap / gridmap: {octo / ours:.1f}x")
    script = str(ROOT / "bench" / "bench_json.py")
    subprocess.run(one_core([sys.executable, script, str(logs["mcap-json"])]), check=True)
    memory_table(logs["laser"], laser_robot, args.repeat)


if __name__ == "__main__":
    main()
