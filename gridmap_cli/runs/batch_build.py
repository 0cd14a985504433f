"""One batch map: a job (:class:`Job`, a log and :class:`BatchOptions`) built by
:func:`gridmap_cli.runs.build.build` as ``gridmap build`` builds it with the same options (the
same bytes), written, and the sidecar saying what it was built from.

The sidecar (``.<map>.batch.json``) holds the key (:func:`gridmap_cli.runs.content.build_key`),
the robot file the map used with its SHA-256 (an edited robot file rebuilds the map, even one a
log names beside itself), and what the overview page shows of a map this run did not build:
readings, cells, warnings, when it was built, its quality and its thumbnail.
"""

from __future__ import annotations

import base64
import dataclasses
import json
import time
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from gridmap_cli import __version__
from gridmap_cli.atomic import atomic_write
from gridmap_cli.errors import naming, naming_style
from gridmap_cli.mapping.options import BuildOptions
from gridmap_cli.poses.sources import DEFAULT_SOURCE
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.runs.content import content_hash

#: The sidecar beside each map, holding the key of what it was built from.
SIDECAR_SUFFIX = ".batch.json"


@dataclass(frozen=True)
class BatchOptions:
    """How every map of a batch is built: ``gridmap build``'s map options, resolved (a robot
    file as an absolute path, the error-aware model's settings as values in ``build``)."""

    build: BuildOptions = field(default_factory=BuildOptions)
    robot: str | None = None  # preset name or absolute path; None: each log's own
    log_format: str | None = None
    pose: str = DEFAULT_SOURCE
    topics: ReadOptions = field(default_factory=ReadOptions)  # without a robot
    sensors: tuple[str, ...] = ()
    start: str | None = None
    end: str | None = None
    map_mode: str = "trinary"
    occupied: float = 0.65
    free: float = 0.25
    image_format: str = "png"

    @property
    def resolution_m(self) -> float:
        return self.build.resolution_m

    def as_dict(self) -> dict[str, Any]:
        """Every option as plain values: what the key of a map holds (processes mapping one
        log are left out: the map is the same bytes for any number)."""
        values = dataclasses.asdict(self)
        del values["build"]["jobs"]
        return values


@dataclass(frozen=True)
class Job:
    """One log and the map to build from it."""

    log: Path
    output: Path  # the map image; its YAML and sidecar go beside it
    options: BatchOptions
    #: how its errors name what was given (the command line's flags, from a worker process)
    naming: str = field(default_factory=naming_style)

    @property
    def sidecar(self) -> Path:
        return self.output.with_name(f".{self.output.stem}{SIDECAR_SUFFIX}")

    @property
    def yaml(self) -> Path:
        return self.output.with_suffix(".yaml")


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
    from gridmap_cli.mapping.selection import Selection
    from gridmap_cli.runs.build import BuildRequest, build
    from gridmap_cli.writers.map_image import write_map
    from gridmap_cli.writers.thumbnail import thumbnail_png

    options = job.options
    request = BuildRequest(
        inputs=(job.log,), robot=options.robot, options=options.build, pose=options.pose,
        selection=Selection.parse(options.sensors, options.start, options.end),
        log_format=options.log_format, read_options=options.topics,
    )  # fmt: skip
    with naming(job.naming):
        result = build(request)
    used_robot_file = robot_file(job, result.log.metadata)
    seconds.update(result.seconds)
    mark = time.perf_counter()
    write_map(job.output, result.map, mode=options.map_mode, occupied_thresh=options.occupied,
              free_thresh=options.free, force=True)  # fmt: skip
    thresholds = (options.occupied, options.free)
    quality = result.quality(thresholds, result.spread()).as_dict()  # as build --json gives it
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
        readings=result.stats.sync.used,
        # the report's reader sees how the track was made where the log had no odometry
        warnings=(
            *result.warnings,
            *((result.placed.posed.motion,) if result.placed.posed.motion else ()),
        ),
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
