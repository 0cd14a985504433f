"""Mapping throughput on a generated 1-hour log: `make bench`.

Simulates (once, cached in bench/.cache/) one hour of a Pioneer 3-AT driving laps of the bundled
corridor loop: 16 sonars at 10 Hz = 576,000 readings. Then times the installed `gridmap build`
command on that log at 5 cm cells, pinned to one core where `taskset` exists, and reports
wall time, readings/s, cell updates/s and peak memory (max RSS of the build process). A phase
breakdown (read, map, write) follows, measured in this process.

Numbers depend on the machine; compare them between commits on the same machine.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / "bench" / ".cache"
WORLD = ROOT / "samples" / "worlds" / "corridor_loop.yaml"
PATH = ROOT / "samples" / "paths" / "corridor_loop.yaml"
DURATION_S = 3600
SEED = 1


def gridmap() -> list[str]:
    exe = Path(sys.executable).with_name("gridmap")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "gridmap_cli"]


def one_core(cmd: list[str]) -> list[str]:
    return ["taskset", "-c", "0", *cmd] if shutil.which("taskset") else cmd


# A wrapper process whose only child is the measured command, so that its RUSAGE_CHILDREN peak
# RSS belongs to that command alone (not to an earlier simulate run of this script).
_WRAPPER = (
    "import resource, subprocess, sys\n"
    "code = subprocess.run(sys.argv[1:]).returncode\n"
    "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr)\n"
    "sys.exit(code)\n"
)


def run_measured(cmd: list[str]) -> tuple[float, int, str]:
    """Run cmd; return wall seconds, peak RSS in MiB and stdout."""
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", _WRAPPER, *cmd], capture_output=True, text=True, check=False
    )
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"bench: command failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stderr}")
    peak_kib = int(proc.stderr.strip().splitlines()[-1])  # KiB on Linux
    return wall, peak_kib // 1024, proc.stdout


def _inputs_digest() -> str:
    """Hash of everything the cached log depends on, so a changed simulator makes a new log."""
    digest = hashlib.sha256()
    sources = sorted((ROOT / "gridmap_cli" / "sim").glob("*.py"))
    for path in [*sources, WORLD, PATH, WORLD.with_suffix(".pgm")]:
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def ensure_log() -> Path:
    CACHE.mkdir(parents=True, exist_ok=True)
    log = CACHE / f"corridor_loop_{DURATION_S}s_seed{SEED}_{_inputs_digest()}.csv"
    if not log.exists():
        print(f"simulating a {DURATION_S} s log (once; cached at {log.relative_to(ROOT)}) ...")
        start = time.perf_counter()
        cmd = [
            *gridmap(),
            "simulate",
            str(WORLD),
            str(PATH),
            "-o",
            str(log),
            "--robot",
            "p3at",
            "--duration",
            str(DURATION_S),
            "--seed",
            str(SEED),
            "--quiet",
        ]
        subprocess.run(cmd, check=True)
        print(f"  simulated in {time.perf_counter() - start:.1f} s")
    return log


def main() -> None:
    log = ensure_log()
    out = CACHE / "bench_map.png"
    cmd = one_core([*gridmap(), "build", str(log), "-o", str(out), "--force", "--quiet", "--json"])
    wall, peak_mib, stdout = run_measured(cmd)
    summary = json.loads(stdout)
    readings = summary["readings"]["used"]
    updates = summary["cell_updates"]
    m = summary["map"]

    from gridmap_cli.pipeline import BuildOptions, build_map
    from gridmap_cli.readers import read_log
    from gridmap_cli.robot import load_robot
    from gridmap_cli.sim.odometry import OdometryErrorModel
    from gridmap_cli.writers.map_image import write_map

    t0 = time.perf_counter()
    data = read_log(log)
    t1 = time.perf_counter()
    result = build_map(data, load_robot("p3at"), BuildOptions())
    t2 = time.perf_counter()
    write_map(CACHE / "bench_map_inproc.png", result.map, force=True)
    t3 = time.perf_counter()

    pinned = "1 core (taskset -c 0)" if shutil.which("taskset") else "unpinned"
    print(f"gridmap build, standard mode, {pinned}, on {os.cpu_count()}-core machine")
    print(f"  log               {log.name}: {summary['readings']['total']:,} readings")
    print(f"  map               {m['width']} x {m['height']} cells at {m['resolution']} m")
    print(f"  wall time         {wall:8.2f} s   (whole command: start-up, read, map, write)")
    print(f"  readings/s        {readings / wall:12,.0f}")
    print(f"  cell updates/s    {updates / wall:12,.0f}   ({updates:,} cell updates)")
    print(f"  peak memory       {peak_mib:8d} MiB (max RSS of the build process)")
    print("  phases (in-process, unpinned):")
    print(f"    read CSV        {t1 - t0:8.2f} s")
    print(
        f"    sync + model    {t2 - t1:8.2f} s   ({len(data.readings) / (t2 - t1):,.0f} readings/s)"
    )
    print(f"    write PNG+YAML  {t3 - t2:8.2f} s")

    # the error-aware mode on the same log, with the simulator's drift-1 error as its f and g
    drift1 = OdometryErrorModel().as_odometry_error().as_dict()
    coefficients = [a for k, v in drift1.items() for a in ("--odometry-coefficient", f"{k}={v!r}")]
    cmd = one_core(
        [
            *gridmap(), "build", str(log), "-o", str(CACHE / "bench_map_ea.png"), "--force",
            "--quiet", "--json", "--mode", "error-aware", *coefficients,
        ]
    )  # fmt: skip
    wall, peak_mib, stdout = run_measured(cmd)
    summary = json.loads(stdout)
    print(f"gridmap build, error-aware mode (drift-1 coefficients), {pinned}")
    print(f"  wall time         {wall:8.2f} s")
    print(f"  readings/s        {summary['readings']['used'] / wall:12,.0f}")
    print(f"  peak memory       {peak_mib:8d} MiB")


if __name__ == "__main__":
    main()
