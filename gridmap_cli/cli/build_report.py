"""What ``gridmap build`` reports of a map it wrote: the ``--json`` summary on standard output,
the one-line summary on standard error, and the warning of a trinary map drawn mostly unknown.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import click
import numpy as np
import numpy.typing as npt

from gridmap_cli.cli.common import json_text
from gridmap_cli.mapping.grid import GridSpec, OccupancyMap
from gridmap_cli.mapping.pipeline import BuildResult

#: Share of the observed cells between the thresholds above which a trinary map warns.
UNDECIDED_SHARE = 0.5


def undecided_note(prob: npt.NDArray[np.float64], occupied: float, free: float) -> tuple[str, ...]:
    """A warning when most observed cells (not NaN) of ``prob`` (rows, cols) fall between the
    thresholds, which a trinary image draws as unknown: the error-aware map of a drifting log."""
    spec = GridSpec(0.0, 0.0, 1.0, prob.shape[1], prob.shape[0])
    observed, high, low = OccupancyMap(spec, prob).cell_counts(occupied, free)
    if observed == 0:
        return ()
    share = float(observed - high - low) / observed
    if share <= UNDECIDED_SHARE:
        return ()
    return (
        f"{100 * share:.0f} % of the observed cells lie between --free {free:g} and --occupied "
        f"{occupied:g} and are drawn unknown in this trinary map (the odometry drifted); "
        "--map-mode scale keeps their probabilities",
    )


def _map_and_cells(omap: OccupancyMap, occupied: float, free: float) -> dict[str, Any]:
    """The summary's "map" (size, cell size in m, origin) and "cells" (counts by threshold)."""
    spec = omap.spec
    observed, high, low = omap.cell_counts(occupied, free)
    return {
        "map": {
            "width": spec.width,
            "height": spec.height,
            "resolution": spec.resolution_m,
            "origin": [spec.origin_x_m, spec.origin_y_m, 0.0],
        },
        "cells": {
            "observed": observed,
            "occupied": high,
            "free": low,
        },
    }


def build_summary(
    result: BuildResult,
    image: Path,
    yaml_path: Path | None,
    seconds: float,
    occupied: float,
    free: float,
) -> dict[str, Any]:
    """The ``--json`` summary of one log's map."""
    return {
        "image": str(image),
        "yaml": str(yaml_path) if yaml_path is not None else None,
        "readings": {
            "total": result.sync.total,
            "used": result.sync.used,
            "skipped": result.sync.total - result.sync.used,
            "outside_odometry": result.sync.outside_odometry,
            "below_min_range": result.sync.below_min_range,
        },
        **_map_and_cells(result.map, occupied, free),
        "cell_updates": result.cell_updates,
        "seconds": round(seconds, 3),
    }


def summary_line(s: dict[str, Any]) -> str:
    """The stderr line of :func:`build_summary` (with its scan matching, if any)."""
    r, m = s["readings"], s["map"]
    matched = ""
    if "scan_match" in s:
        sm = s["scan_match"]
        matched = (
            f"; {sm['scans']:,} scans matched in {sm['seconds']:.1f} s, {sm['fallbacks']:,} fell "
            f"back to odometry, {sm['degenerate']:,} degenerate (odometry along the corridor), "
            f"{sm['partial']:,} on the part the local map saw"
        )
    if "slam" in s:
        sl = s["slam"]
        matched = (
            f"; slam: {sl['closures_accepted']:,} loop closures accepted, "
            f"{sl['closures_rejected']:,} rejected, {sl['fallbacks']:,} scans fell back to "
            f"odometry{widened_clause(sl)}"
        )
    choice = s.get("pose_choice")
    if choice is not None and choice["source"] != "odometry":
        matched = f"; poses: {choice['source']} (the automatic choice: {choice['because']})" + (
            matched
        )
    skipped = ""
    if r["skipped"]:
        skipped = (
            f" ({r['skipped']:,} skipped: {r['outside_odometry']:,} outside the odometry's time "
            f"span, {r['below_min_range']:,} below minimum range)"
        )
    return (
        f"gridmap: {r['used']:,} of {r['total']:,} readings mapped{skipped}; "
        f"{m['width']} x {m['height']} cells at {m['resolution']} m "
        f"({m['width'] * m['resolution']:.1f} x {m['height'] * m['resolution']:.1f} m) "
        f"in {s['seconds']:.1f} s -> {s['image']}"
        + (f", {s['yaml']}" if s["yaml"] else "")
        + (f", {s['preview']} (the tracks drawn on the map)" if s.get("preview") else "")
        + matched
        + ("; the odometry's calibrated biases corrected" if s.get("odometry_corrected") else "")
        + (f"; {s['motion']}" if s.get("motion") else "")
        + (f"; {s['odometry_check_note']}" if s.get("odometry_check_note") else "")
    )


def fused_summary(
    omap: OccupancyMap,
    readings: int,
    image: Path,
    yaml_path: Path | None,
    n_logs: int,
    seconds: float,
    occupied: float,
    free: float,
) -> dict[str, Any]:
    """The ``--json`` summary of a ``--fuse`` map of ``n_logs`` logs."""
    return {
        "image": str(image),
        "yaml": str(yaml_path) if yaml_path is not None else None,
        "logs": n_logs,
        "readings": {"used": readings},
        **_map_and_cells(omap, occupied, free),
        "seconds": round(seconds, 3),
    }


def fused_line(s: dict[str, Any]) -> str:
    """The stderr line of :func:`fused_summary`."""
    m = s["map"]
    return (
        f"gridmap: {s['logs']} logs fused, {s['readings']['used']:,} readings mapped; "
        f"{m['width']} x {m['height']} cells at {m['resolution']} m in {s['seconds']:.1f} s -> "
        f"{s['image']}" + (f", {s['yaml']}" if s["yaml"] else "")
    )


def report(summary: dict[str, Any], line: str, as_json: bool, quiet: bool) -> None:
    """Print ``summary`` as JSON on stdout (``--json``) and ``line`` on stderr (unless -q)."""
    if as_json:
        click.echo(json_text(summary))
    if not quiet:
        click.echo(line, err=True)


def widened_clause(slam: Mapping[str, Any]) -> str:
    """The summary's clause on a closure search run again wider (empty where it was not)."""
    # here, not at the top: the pose graph's modules load gtsam, which a build without slam
    # never needs (and a slam build has loaded already)
    from gridmap_cli.poses.correction.repair import widening

    said = widening(slam.get("closure_search_widened_for"), slam["closure_search_widened"])
    return "" if said is None else f", {said}"
