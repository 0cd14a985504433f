"""How far the proving ground's slam rows move by chance: each log's slam track again with its
odometry jittered far under any real odometry's noise per step (``real_logs.jittered``: 0.5 mm and
0.005 degree per step, one seed per run), so a change to the method can be judged against the
spread of its own rows instead of against one draw.

The table: per log, the unjittered figure (seed "-"), each seed's, and their range. Relations'
mean translational error on the raw bags, APE RMSE against the corrected poses on CARMEN (as
``bench/real_logs.py``).

    nice .venv/bin/python bench/slam_spread.py --seeds 1,2,3 --jobs 2
    nice .venv/bin/python bench/slam_spread.py --logs aces,acapulco --seeds 1,2 --pose scan-matched
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor

from real_logs import BAGS, CARMEN, SOURCES, jobs_for, run_bag, run_carmen


def _one(job: tuple[str, str, str, int | None]) -> tuple[str, str, int | None, str]:
    kind, name, source, seed = job
    started = time.perf_counter()
    run = run_bag if kind == "bag" else run_carmen
    row = run(name, (source,), jitter=seed)
    cell = row.cells[source]
    text = cell.error or (f"{cell.value[0]:.3f}" if cell.value else "?")
    if cell.note and "warned: " in cell.note:
        text += " (free space warned)"
    print(
        f"{kind} {name} seed {seed}: {text} in {time.perf_counter() - started:.0f} s; {cell.note}",
        file=sys.stderr,
        flush=True,
    )
    return kind, name, seed, text


def table(results: list[tuple[str, str, int | None, str]], seeds: list[int | None]) -> list[str]:
    """One row per log: each seed's figure, then the range over the seeds that scored."""
    head = "| log | " + " | ".join("-" if s is None else str(s) for s in seeds) + " | range |"
    lines = [head, "|" + "---|" * (len(seeds) + 2)]
    by_row: dict[tuple[str, str], dict[int | None, str]] = {}
    for kind, name, seed, text in results:
        by_row.setdefault((kind, name), {})[seed] = text
    for (kind, name), cells in by_row.items():
        values = [float(t.split()[0]) for t in cells.values() if t[:1].isdigit()]
        spread = f"{min(values):.3f}-{max(values):.3f}" if values else "-"
        label = f"{name} {'bag' if kind == 'bag' else 'CARMEN'}"
        row = " | ".join(cells.get(s, "?") for s in seeds)
        lines.append(f"| {label} | {row} | {spread} |")
    return lines


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    names = sorted({*BAGS, *CARMEN})
    parser.add_argument("--logs", help=f"comma-separated, of {', '.join(names)} (default: all)")
    parser.add_argument("--seeds", default="1,2,3", help="comma-separated jitter seeds")
    parser.add_argument("--no-plain", action="store_true", help="skip the unjittered run")
    parser.add_argument("--pose", default="slam", choices=SOURCES[1:], help="the source scored")
    parser.add_argument("--jobs", type=int, default=1, help="runs at a time")
    args = parser.parse_args(argv)
    logs = None if args.logs is None else [n for n in args.logs.split(",") if n]
    seeds: list[int | None] = [] if args.no_plain else [None]
    seeds += [int(s) for s in args.seeds.split(",") if s]
    work = [(kind, name, args.pose, seed) for kind, name in jobs_for(logs) for seed in seeds]
    if not work:
        print("none of the logs is present: nothing to measure", file=sys.stderr)
        return
    if args.jobs > 1:
        with ProcessPoolExecutor(max_workers=args.jobs) as pool:
            results = list(pool.map(_one, work))
    else:
        results = [_one(w) for w in work]
    print("\n".join(table(results, seeds)))


if __name__ == "__main__":
    main()
