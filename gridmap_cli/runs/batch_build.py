"""One batch map: a log read, its poses chosen, mapped and written as ``gridmap build`` does
with the same options (the same bytes), and the sidecar saying what it was built from.

The sidecar (``.<map>.batch.json``) holds the key (:func:`gridmap_cli.runs.content.build_key`),
the robot file the map used with its SHA-256 (an edited robot file rebuilds the map, even one a
log names beside itself), and what the overview page shows of a map this run did not build:
readings, cells, warnings, when it was built and its thumbnail.
"""

from __future__ import annotations

import base64
import dataclasses
import json
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from gridmap_cli import __version__
from gridmap_cli.atomic import atomic_write
from gridmap_cli.runs.content import content_hash

if TYPE_CHECKING:
    from gridmap_cli.evaluation.quality import FloatArray
    from gridmap_cli.mapping.grid import OccupancyMap
    from gridmap_cli.mapping.options import BuildOptions
    from gridmap_cli.poses.correction.pose_graph import Edge
    from gridmap_cli.records import RangeLog
    from gridmap_cli.robot import RobotDescription
    from gridmap_cli.runs.batch import Job

#: --pose values whose track the laser makes (the readings are held for it)
LASER_POSES = ("scan-matched", "slam")


@dataclasses.dataclass(frozen=True)
class Built:
    """What building one map found: ``cells`` (width, height, observed, occupied, free),
    readings mapped, and the warnings a build would print."""

    cells: dict[str, int]
    readings: int
    warnings: tuple[str, ...]
    built_at: str
    #: what the log tells of the map (:meth:`gridmap_cli.evaluation.quality.Quality.as_dict`)
    quality: dict[str, Any] | None = None


def robot_file(job: Job, metadata: dict[str, str] | None) -> Path | None:
    """The robot description file a map is built with: ``--robot FILE``, or the file a log's
    ``# robot:`` line names beside it; None for a preset or no robot."""
    from gridmap_cli.robot import preset_names

    spec = job.options.robot
    if spec is not None:
        return None if spec in preset_names() else Path(spec)
    name = (metadata or {}).get("robot")
    if not name or name in preset_names():
        return None
    path = job.log.parent / name
    return path if path.is_file() else None


def robot_file_entry(path: Path | None) -> dict[str, str] | None:
    return None if path is None else {"path": str(path), "sha256": content_hash(path)[0]}


def read_sidecar(job: Job) -> dict[str, Any] | None:
    """The sidecar beside ``job``'s map, or None when it is missing or unreadable."""
    try:
        stored = json.loads(job.sidecar.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return stored if isinstance(stored, dict) else None


def up_to_date(job: Job, key: str) -> dict[str, Any] | None:
    """The sidecar of ``job``'s map when the map is up to date: the map, its YAML and sidecar
    exist, the sidecar holds ``key``, and the robot file it was built with is unchanged."""
    if not (job.output.is_file() and job.yaml.is_file()):
        return None
    stored = read_sidecar(job)
    if stored is None or stored.get("key") != key:
        return None
    robot = stored.get("robot_file")
    if robot is not None:
        try:
            if robot_file_entry(Path(robot["path"])) != robot:
                return None
        except (OSError, KeyError, TypeError):
            return None
    return stored


def build_job(job: Job, key: str, seconds: dict[str, float]) -> Built:
    """Build ``job``'s map, its YAML and sidecar (``seconds`` gets read, map and write times)."""
    from gridmap_cli.mapping.pipeline import build_map, reference_spread_note
    from gridmap_cli.mapping.selection import Selection, apply_selection
    from gridmap_cli.poses.sync import select_poses
    from gridmap_cli.readers import read_logs
    from gridmap_cli.robot import load_robot, robot_from_log
    from gridmap_cli.writers.map_image import write_map
    from gridmap_cli.writers.thumbnail import thumbnail_png

    mark = time.perf_counter()
    options = job.options
    robot = load_robot(options.robot) if options.robot else None
    selection = Selection.parse(options.sensors, options.start, options.end)
    # a long log's readings stay in its file unless scan matching or a time window needs them
    stream = options.pose not in LASER_POSES and selection.start is None and selection.end is None
    read_options = dataclasses.replace(options.topics, robot=robot, stream=stream)
    data = read_logs([job.log], options.log_format, read_options)
    used_robot_file = robot_file(job, data.metadata)
    if robot is None:
        robot = robot_from_log(job.log, data.metadata)
    warnings: list[str] = []
    build = options.build
    belief = None
    graph = None
    if options.pose == "scan-matched":
        from gridmap_cli.poses.correction.scan_match import (
            scan_matched_log,
        )  # scipy, small_gicp: only here

        data, _ = scan_matched_log(data, robot)
    elif options.pose == "slam":
        from gridmap_cli.poses.correction.slam import slam_corrected_log  # gtsam: only here

        data, slam = slam_corrected_log(data, robot)
        if slam.warning:
            warnings.append(f"--pose slam: {slam.warning}")
        from gridmap_cli.poses.uncertainty.pose_belief import slam_belief

        # the graph's marginals (the quality's spread) and, error-aware, its draws
        samples = build.error_samples if build.mode == "error-aware" else 0
        belief = slam_belief(slam, samples, build.error_seed)
        if build.mode == "error-aware":
            build = dataclasses.replace(build, pose_belief=belief)
        if slam.graph is not None:
            graph = (slam.poses, slam.graph.edges)
    else:
        data = select_poses(data, options.pose)
        note = reference_spread_note(options.pose, build)
        if note is not None:
            warnings.append(note)
    selected = apply_selection(dataclasses.replace(data, truth=None), selection, robot)
    warnings.extend(selected.notes)
    seconds["read"] = time.perf_counter() - mark
    mark = time.perf_counter()
    result = build_map(selected.log, robot, build)
    seconds["map"] = time.perf_counter() - mark
    mark = time.perf_counter()
    write_map(job.output, result.map, mode=options.map_mode, occupied_thresh=options.occupied,
              free_thresh=options.free, force=True)  # fmt: skip
    quality = _quality(selected.log, robot, dataclasses.replace(build, pose_belief=belief),
                       result.map, (options.occupied, options.free), graph)  # fmt: skip
    prob = result.map.prob
    known = ~np.isnan(prob)
    built = Built(
        cells={
            "width": result.map.spec.width,
            "height": result.map.spec.height,
            "observed": int(known.sum()),
            "occupied": int((prob[known] >= options.occupied).sum()),
            "free": int((prob[known] <= options.free).sum()),
        },
        readings=result.sync.used,
        warnings=tuple(warnings),
        built_at=datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        quality=quality,
    )
    thumbnail = thumbnail_png(prob, options.occupied, options.free)
    sidecar = {
        "key": key,
        "log": str(job.log),
        "options": options.as_dict(),
        "gridmap": __version__,
        "robot_file": robot_file_entry(used_robot_file),
        "cells": built.cells,
        "readings": built.readings,
        "warnings": list(built.warnings),
        "built_at": built.built_at,
        "quality": built.quality,
        "thumbnail_png": base64.b64encode(thumbnail).decode("ascii"),
    }
    with atomic_write(job.sidecar, "the batch sidecar") as tmp:
        tmp.write_text(json.dumps(sidecar, sort_keys=True) + "\n", encoding="utf-8")
    seconds["write"] = time.perf_counter() - mark
    return built


def _quality(
    log: RangeLog,
    robot: RobotDescription | None,
    build: BuildOptions,
    omap: OccupancyMap,
    thresholds: tuple[float, float],
    graph: tuple[FloatArray, list[Edge]] | None,
) -> dict[str, Any]:
    """The quality block ``gridmap build --json`` gives the same map."""
    from gridmap_cli.evaluation.quality import map_quality, map_spread

    spread = None
    if build.mode == "error-aware" or build.pose_belief is not None:
        spread = map_spread(log, robot, build, omap)
    return map_quality(log, robot, build, omap, thresholds, spread, graph).as_dict()


def sidecar_thumbnail(job: Job) -> bytes | None:
    """The PNG thumbnail a map's sidecar holds, or None."""
    stored = read_sidecar(job)
    text = stored.get("thumbnail_png") if stored is not None else None
    if not isinstance(text, str):
        return None
    try:
        return base64.b64decode(text, validate=True)
    except ValueError:
        return None
