"""Quality without ground truth against the NLL with it: does the log's own score rank the maps
of odometry, scan matching and the pose graph as the reference does?

For each shared CARMEN log (``../shared/data/carmen``) three standard maps are built, as
``gridmap build --pose odometry|scan-matched|slam`` builds them (0.05 m), and each is scored two
ways:

- **with the reference**: NLL (nats per cell) of the reference map's occupied and free cells
  (the map built from the corrected poses), the map carried into it by the rigid alignment that
  best lays its track on the reference track, as ``bench/scan_match.py`` scores a map;
- **without it**: what ``gridmap evaluate MAP --log LOG`` reports
  (:mod:`gridmap_cli.evaluation.quality`): the share of the laser's echoes that end in a cell
  the map calls free (lower is better), and for the pose graph the median NEES of its closures.

Nothing is fitted: the score is the echo share as defined, the same for every log. Writes the
table to docs/quality.md between its markers.

    nice .venv/bin/python bench/quality_ranking.py
    .venv/bin/python bench/quality_ranking.py --logs aces --no-doc
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.scan_match import map_scores  # noqa: E402
from gridmap_cli.evaluation.quality import (  # noqa: E402
    ClosureConsistency,
    EchoConsistency,
    closure_consistency,
    echo_consistency,
    map_readings,
)
from gridmap_cli.mapping.pipeline import BuildOptions, build_map  # noqa: E402
from gridmap_cli.poses.correction.scan_match import corrected_track, match_log  # noqa: E402
from gridmap_cli.poses.correction.slam import slam_log  # noqa: E402
from gridmap_cli.poses.sync import interpolate_pose  # noqa: E402
from gridmap_cli.poses.track_error import track_error  # noqa: E402
from gridmap_cli.readers import read_logs  # noqa: E402
from gridmap_cli.readers.options import ReadOptions  # noqa: E402
from gridmap_cli.records import PoseTrack  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "carmen"
LOGS = ("intel", "aces", "freiburg-079", "seattle", "acapulco", "belgioioso")
SOURCES = ("odometry", "scan-matched", "slam")
DOC = ROOT / "docs" / "quality.md"
OCCUPIED, FREE = 0.65, 0.25
DELTA_M = 5.0


@dataclass(frozen=True)
class Row:
    source: str
    ape_m: float
    nll: float
    echoes: EchoConsistency | None
    closures: ClosureConsistency | None


def run_log(name: str) -> list[Row]:
    log = read_logs((DATA / f"{name}-corrected.log.gz",), None, ReadOptions())
    assert log.truth is not None
    slam = slam_log(log, None)
    match = match_log(log, None)  # build --pose scan-matched's own matcher, not the graph's
    stamps = slam.track.stamp_ns
    rx, ry, rth, _ = interpolate_pose(log.truth, stamps)
    reference = PoseTrack(stamp_ns=stamps, x_m=rx, y_m=ry, theta_rad=rth)
    options = BuildOptions()
    ref_map = build_map(dataclasses.replace(log, poses=log.truth), None, options).map
    logs = {
        "odometry": log,
        "scan-matched": dataclasses.replace(log, poses=corrected_track(log.poses, match)),
        "slam": dataclasses.replace(log, poses=corrected_track(log.poses, slam.match)),
    }
    tracks = {
        "odometry": match.odometry,
        "scan-matched": match.track,
        "slam": slam.track,
    }
    rows = []
    for source in SOURCES:
        omap = build_map(logs[source], None, options).map
        error = track_error(tracks[source], reference, DELTA_M)
        _, _, _, nll = map_scores(omap, ref_map, error.alignment)
        echoes = echo_consistency(omap, map_readings(logs[source], None, options), OCCUPIED, FREE)
        closures = None
        if source == "slam" and slam.graph is not None:
            closures = closure_consistency(slam.poses, slam.graph.edges)
        rows.append(Row(source, error.ape_rmse_m, nll, echoes, closures))
    return rows


def ranks(values: list[float]) -> list[int]:
    """1 for the smallest value; ties share the rank."""
    return [sorted(values).index(v) + 1 for v in values]


def table(results: dict[str, list[Row]]) -> tuple[list[str], int]:
    lines = [
        "| log | map | track APE m | NLL against the reference | rank | echoes | "
        "echoes in free cells | rank | echoes in occupied cells | closures, median NEES |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    agree = 0
    for name, rows in results.items():
        nll_rank = ranks([r.nll for r in rows])
        own = [r.echoes.in_free if r.echoes is not None else float("nan") for r in rows]
        own_rank = ranks(own)
        agree += nll_rank == own_rank
        for r, a, b in zip(rows, nll_rank, own_rank, strict=True):
            e = r.echoes
            c = r.closures
            lines.append(
                f"| {name} | {r.source} | {r.ape_m:.2f} | {r.nll:.4f} | {a} | "
                f"{e.echoes if e else 0:,} | {e.in_free if e else float('nan'):.4f} | {b} | "
                f"{e.in_occupied if e else float('nan'):.3f} | "
                + (f"{c.closures:,}, {c.median_nees:.2f} |" if c else "- |")
            )
    return lines, agree


def write_doc(lines: list[str], agree: int, total: int, path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    block = "\n".join(
        [
            "<!-- quality-ranking: generated by bench/quality_ranking.py -->",
            *lines,
            "",
            f"The echo share ranks the three maps as the NLL does on {agree} of {total} logs.",
            "<!-- /quality-ranking -->",
        ]
    )
    pattern = re.compile(
        r"<!-- quality-ranking: .*?-->.*?<!-- /quality-ranking -->", flags=re.DOTALL
    )
    path.write_text(pattern.sub(lambda _: block, text), encoding="utf-8")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", nargs="+", default=list(LOGS), choices=LOGS)
    parser.add_argument("--no-doc", action="store_true", help="print the table only")
    args = parser.parse_args(argv)
    if not DATA.is_dir():
        sys.exit(f"{DATA} is not present: nothing to measure")
    started = time.perf_counter()
    results = {}
    for name in args.logs:
        results[name] = run_log(name)
        print(f"{name} done, {time.perf_counter() - started:.0f} s", file=sys.stderr, flush=True)
    lines, agree = table(results)
    print("\n".join(lines))
    print(f"agree on {agree} of {len(results)} logs")
    if not args.no_doc:
        write_doc(lines, agree, len(results), DOC)
        print(f"wrote {DOC}")


if __name__ == "__main__":
    main()
