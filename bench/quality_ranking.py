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
  the map calls free (lower is better), the revisits (:mod:`gridmap_cli.evaluation.revisits`:
  the distance between two visits' echoes on the places the pose graph found twice, its median
  and its mean over the places, the graph's own track on the closures held out of its solve;
  lower is better), the cells the map knows (lower is better: a pass the track puts where no
  other pass was uncovers cells of its own; ``bench/quality_cases.py``), and for the pose graph
  the median NEES of its closures.

Nothing is fitted: each score is as defined, the same for every log. The CPU seconds of the
revisits (the scans' echoes summed up and the held-out solves) are printed beside those of the
pose graph they come from. Writes the table to docs/quality.md between its markers.

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

import numpy as np

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
from gridmap_cli.evaluation.revisits import (  # noqa: E402
    RevisitScore,
    graph_revisits,
    map_revisits,
    score_track,
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
    revisits: RevisitScore | None
    known_cells: int


@dataclass(frozen=True)
class Found:
    """What the pose graph found in one log: the corrected-pose reference on its revisits, and
    the CPU seconds of the graph and of the revisits (echoes summed up, held-out solves)."""

    reference: RevisitScore | None
    graph_s: float
    revisits_s: float


def run_log(name: str) -> tuple[list[Row], Found]:
    """The three rows of one log and what its pose graph found."""
    log = read_logs((DATA / f"{name}-corrected.log.gz",), None, ReadOptions())
    assert log.truth is not None
    cpu = time.process_time()
    slam = slam_log(log, None)
    graph_s = time.process_time() - cpu
    cpu = time.process_time()
    revisits = graph_revisits(slam, log, None)
    revisits_s = time.process_time() - cpu
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
        own = map_revisits(revisits, logs[source].poses, graph_track=source == "slam")
        known = int(np.count_nonzero(~np.isnan(omap.prob)))
        rows.append(Row(source, error.ape_rmse_m, nll, echoes, closures, own, known))
    on_revisits = None if revisits is None else score_track(log.truth, revisits)
    return rows, Found(on_revisits, graph_s, revisits_s)


def ranks(values: list[float]) -> list[int]:
    """1 for the smallest value; ties share the rank."""
    return [sorted(values).index(v) + 1 for v in values]


def table(results: dict[str, list[Row]]) -> tuple[list[str], dict[str, int]]:
    """The table, and on how many logs each score ranks the three maps as the NLL does."""
    lines = [
        "| log | map | track APE m | NLL against the reference | rank | echoes | "
        "echoes in free cells | rank | revisits | apart, median m | rank | mean m | rank | "
        "mean deg | known cells | rank | closures, median NEES |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    agree = dict.fromkeys(("echo share", "revisits median", "revisits mean", "known cells"), 0)
    nan = float("nan")
    for name, rows in results.items():
        nll_rank = ranks([r.nll for r in rows])
        own_rank = ranks([r.echoes.in_free if r.echoes is not None else nan for r in rows])
        apart_rank = ranks([r.revisits.median_m if r.revisits is not None else nan for r in rows])
        mean_rank = ranks([r.revisits.mean_m if r.revisits is not None else nan for r in rows])
        known_rank = ranks([float(r.known_cells) for r in rows])
        agree["echo share"] += nll_rank == own_rank
        agree["revisits median"] += nll_rank == apart_rank
        agree["revisits mean"] += nll_rank == mean_rank
        agree["known cells"] += nll_rank == known_rank
        for r, a, b, d, m, k in zip(
            rows, nll_rank, own_rank, apart_rank, mean_rank, known_rank, strict=True
        ):
            e = r.echoes
            c = r.closures
            v = r.revisits
            held = " (held out)" if v is not None and v.held_out else ""
            lines.append(
                f"| {name} | {r.source} | {r.ape_m:.2f} | {r.nll:.4f} | {a} | "
                f"{e.echoes if e else 0:,} | {e.in_free if e else nan:.4f} | {b} | "
                + (
                    f"{v.relations:,}{held} | {v.median_m:.3f} | {d} | {v.mean_m:.3f} | {m} | "
                    f"{v.rot_mean_deg:.2f} | "
                    if v
                    else "- | - | - | - | - | - | "
                )
                + f"{r.known_cells:,} | {k} | "
                + (f"{c.closures:,}, {c.median_nees:.2f} |" if c else "- |")
            )
    return lines, agree


def found_table(found: dict[str, Found]) -> list[str]:
    """The revisits each log's pose graph found, the reference's score on them, the costs."""
    lines = [
        "| log | revisits | reference: apart, median m | mean m | mean deg | CPU s: pose graph | "
        "revisits |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, f in found.items():
        r = f.reference
        scores = f"{r.median_m:.3f} | {r.mean_m:.3f} | {r.rot_mean_deg:.2f}" if r else "- | - | -"
        lines.append(
            f"| {name} | {r.relations if r else 0:,} | {scores} | {f.graph_s:.1f} | "
            f"{f.revisits_s:.2f} |"
        )
    return lines


def agreement(agree: dict[str, int], total: int) -> str:
    return (
        "The three maps are ranked as the NLL ranks them on "
        + ", ".join(f"{n} of {total} logs by the {s}" for s, n in agree.items())
        + "."
    )


def write_doc(lines: list[str], agree: dict[str, int], total: int, path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    block = "\n".join(
        [
            "<!-- quality-ranking: generated by bench/quality_ranking.py -->",
            *lines,
            "",
            agreement(agree, total),
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
    found: dict[str, Found] = {}
    for name in args.logs:
        results[name], found[name] = run_log(name)
        print(f"{name} done, {time.perf_counter() - started:.0f} s", file=sys.stderr, flush=True)
    lines, agree = table(results)
    lines += ["", *found_table(found)]
    print("\n".join(lines))
    print(agreement(agree, len(results)))
    if not args.no_doc:
        write_doc(lines, agree, len(results), DOC)
        print(f"wrote {DOC}")


if __name__ == "__main__":
    main()
