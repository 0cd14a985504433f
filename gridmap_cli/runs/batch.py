"""Batch runs for cron: one map per log, skipping logs whose map is up to date.

:func:`find_logs` turns the inputs (files, folders, globs) into logs; :func:`plan_jobs` names one
map per log; :func:`run_job` builds one map and never raises (a failed log is a result, so a
batch continues past it); :func:`run_batch` runs the jobs on an executor (in this process, local
processes, or a Dask cluster, :mod:`gridmap_cli.runs.executors`) and reports each as it finishes
(on Ctrl-C, those that finished); :func:`write_overview` writes ``OUTDIR/index.html`` from the
results (:mod:`gridmap_cli.writers.overview`). :mod:`gridmap_cli.runs.batch_build` builds a map.

Up to date means: the map, its YAML and its sidecar (``.<map>.batch.json``) exist and the
sidecar's key is the SHA-256 of the log's content (every file of a rosbag2 folder), every
option that changes the map (:class:`BatchOptions`) and gridmap's version, and the robot file
the map used is unchanged. Touching a log without changing it rebuilds nothing; changing a byte
of it, of its robot file, or an option, rebuilds its map.

:class:`BatchLock` keeps two batch runs off one output folder: an advisory ``flock`` on
``OUTDIR/.gridmap-batch.lock``, released by the kernel when its holder exits or is killed, so a
crashed run never leaves a stale lock.
"""

from __future__ import annotations

import contextlib
import dataclasses
import fcntl
import glob
import json
import os
import time
from collections import Counter
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from gridmap_cli import __version__
from gridmap_cli.atomic import atomic_write
from gridmap_cli.errors import GridmapError, UsageError
from gridmap_cli.runs.batch_build import SIDECAR_SUFFIX as SIDECAR_SUFFIX
from gridmap_cli.runs.batch_build import BatchOptions as BatchOptions
from gridmap_cli.runs.batch_build import Job as Job
from gridmap_cli.runs.batch_build import build_job, sidecar_thumbnail, up_to_date
from gridmap_cli.runs.content import build_key, content_hash

LOCK_NAME = ".gridmap-batch.lock"
REPORT_NAME = "batch-report.jsonl"
OVERVIEW_NAME = "index.html"
_GLOB_CHARS = "*?["


@dataclass(frozen=True)
class JobResult:
    """What became of one job: ``status`` is ``built``, ``skipped`` (up to date) or ``failed``."""

    log: str
    map: str
    status: str
    error: str | None = None
    seconds: dict[str, float] = field(default_factory=dict)
    input_bytes: int = 0
    map_bytes: int = 0
    cells: dict[str, int] = field(default_factory=dict)
    key: str = ""
    readings: int = 0  # readings mapped
    warnings: tuple[str, ...] = ()
    built_at: str = ""  # UTC time the map was built (this run, or the run that built it)
    #: what the log tells of the map (docs/quality.md); empty for a failed job
    quality: dict[str, Any] = field(default_factory=dict)

    def as_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), sort_keys=True)


# ----------------------------------------------------------------------------------- inputs


def is_log_name(path: Path) -> bool:
    """True for a file whose extension is a log format's (``.gz`` of a text log included)."""
    from gridmap_cli.readers import FORMATS

    suffixes = [s.lower() for s in path.suffixes]
    if suffixes[-1:] == [".gz"]:
        suffixes = suffixes[:-1]
    return bool(suffixes) and any(
        suffixes[-1] in f.extensions + f.weak_extensions for f in FORMATS if f.name != "rosbag2"
    )


def find_logs(inputs: Sequence[str]) -> list[Path]:
    """The logs the inputs name: a file is a log; a rosbag2 folder is one log; another folder
    holds logs (files with a log extension and rosbag2 folders, not recursing further); a glob
    (``*``, ``?``, ``[``; ``**`` recurses) names files and folders as above. Resolved (links
    followed), sorted, each once: a file reached twice (a symbolic link loop under ``**``, a
    link beside its target) is one log.

    Raises :class:`UsageError` naming an input that matches nothing.
    """
    from gridmap_cli.readers.ros.bag.log import is_rosbag2

    found: dict[Path, None] = {}
    for text in inputs:
        if any(c in text for c in _GLOB_CHARS) and not Path(text).exists():
            paths = [Path(p) for p in sorted(glob.glob(text, recursive=True))]
        else:
            paths = [Path(text)]
        matched = False
        for path in paths:
            if path.is_dir() and not is_rosbag2(path):
                inside = sorted(path.iterdir())
                logs = [p for p in inside if (p.is_file() and is_log_name(p)) or is_rosbag2(p)]
            elif path.exists():
                logs = [path]
            else:
                continue
            for log in logs:
                found[log.resolve()] = None
                matched = True
        if not matched:
            raise UsageError(f"{text}: no log there (a log file, a folder of logs, or a glob)")
    return sorted(found)


def plan_jobs(logs: Sequence[Path], outdir: Path, options: BatchOptions) -> list[Job]:
    """One map per log in ``outdir``, named after the log: ``run.mcap`` -> ``run.png`` (or the
    options' image format).

    Logs that share a stem (``run.csv`` and ``run.mcap``) are told apart by their extension
    (``run-csv.png``, ``run-mcap.png``), so a name depends only on the inputs of the run.
    """
    stems = Counter(_stem(log) for log in logs)
    jobs = []
    for log in logs:
        stem = _stem(log)
        if stems[stem] > 1:
            ext = log.name[len(stem) :].lstrip(".").replace(".", "-") or "dir"
            stem = f"{stem}-{ext}"
        jobs.append(Job(log, outdir / f"{stem}.{options.image_format}", options))
    names = Counter(job.output.name for job in jobs)
    twice = sorted(name for name, n in names.items() if n > 1)
    if twice:
        clash = [str(job.log) for job in jobs if job.output.name == twice[0]]
        raise UsageError(
            f"several logs would write {twice[0]}: {' and '.join(clash)} (the same name in "
            "different folders); run them into separate output folders"
        )
    return jobs


def _stem(log: Path) -> str:
    name = log.name
    if name.lower().endswith(".gz"):
        name = name[:-3]
    return Path(name).stem if not log.is_dir() else name


# ------------------------------------------------------------------------------ up to date


def job_key(content: str, options: BatchOptions) -> str:
    """The key a map is built from: log content, options and gridmap's version."""
    return build_key(content, options.as_dict(), __version__)


# ------------------------------------------------------------------------------------ jobs


def run_job(job: Job) -> JobResult:
    """Build one job's map unless it is up to date; never raises (a failure is a result).

    Runs in whatever process the executor chose: everything it needs is in ``job``.
    """
    started = time.perf_counter()
    seconds: dict[str, float] = {}
    input_bytes = 0
    key = ""
    try:
        content, input_bytes = content_hash(job.log)
        key = job_key(content, job.options)
        seconds["hash"] = time.perf_counter() - started
        stored = up_to_date(job, key)
        if stored is not None:
            return dataclasses.replace(
                _result(job, "skipped", None, seconds, started, input_bytes, key),
                cells=dict(stored.get("cells") or {}),
                readings=int(stored.get("readings") or 0),
                warnings=tuple(str(w) for w in stored.get("warnings") or ()),
                built_at=str(stored.get("built_at") or ""),
                quality=dict(stored.get("quality") or {}),
            )
        built = build_job(job, key, seconds)
    except GridmapError as exc:
        return _result(job, "failed", _one_line(str(exc)), seconds, started, input_bytes, key)
    except OSError as exc:
        error = f"{exc.filename or job.log}: {exc.strerror or exc}"
        return _result(job, "failed", error, seconds, started, input_bytes, key)
    except MemoryError:
        return _result(job, "failed", f"{job.log}: out of memory", seconds, started,
                       input_bytes, key)  # fmt: skip
    except Exception as exc:  # a batch continues past anything one log does
        error = f"{job.log}: internal error ({type(exc).__name__}: {_one_line(str(exc))[:300]})"
        return _result(job, "failed", error, seconds, started, input_bytes, key)
    return dataclasses.replace(
        _result(job, "built", None, seconds, started, input_bytes, key, built.cells),
        readings=built.readings,
        warnings=built.warnings,
        built_at=built.built_at,
        quality=built.quality or {},
    )


def _result(
    job: Job,
    status: str,
    error: str | None,
    seconds: dict[str, float],
    started: float,
    input_bytes: int,
    key: str,
    cells: dict[str, int] | None = None,
) -> JobResult:
    seconds = {k: round(v, 3) for k, v in seconds.items()}
    seconds["total"] = round(time.perf_counter() - started, 3)
    map_bytes = sum(p.stat().st_size for p in (job.output, job.yaml) if p.is_file())
    return JobResult(
        log=str(job.log),
        map=str(job.output),
        status=status,
        error=error,
        seconds=seconds,
        input_bytes=input_bytes,
        map_bytes=map_bytes if status != "failed" else 0,
        cells=cells or {},
        key=key,
    )


def _one_line(text: str) -> str:
    return " ".join(part.strip() for part in text.splitlines() if part.strip())


# ----------------------------------------------------------------------------------- runs


@dataclass(frozen=True)
class BatchSummary:
    """The results of a run, in the order of its jobs: every job's, or, when the run was
    ``interrupted`` (Ctrl-C), those that finished before it, of ``total`` jobs."""

    results: list[JobResult]
    total: int
    interrupted: bool = False

    def count(self, status: str) -> int:
        return sum(1 for r in self.results if r.status == status)

    @property
    def failed(self) -> int:
        return self.count("failed")


def run_batch(
    jobs: Sequence[Job],
    submit: Callable[[Sequence[Job]], Generator[JobResult, None, None]],
    report: Path,
    on_result: Callable[[JobResult], object] | None = None,
) -> BatchSummary:
    """Run ``jobs`` through ``submit`` (an executor's map, results in any order) and write the
    JSON-lines ``report`` (one line per log, in the order of ``jobs``) atomically at the end.

    ``on_result`` is called with each result as it arrives (a progress bar). Ctrl-C
    (KeyboardInterrupt) stops the executor (closing its generator ends its workers) and the
    report holds the jobs that had finished; the summary says it was interrupted.
    """
    by_map: dict[str, JobResult] = {}
    interrupted = False
    try:
        with contextlib.closing(submit(jobs)) as results_in:
            for result in results_in:
                by_map[result.map] = result
                if on_result is not None:
                    on_result(result)
    except KeyboardInterrupt:
        interrupted = True
    results = [by_map[str(job.output)] for job in jobs if str(job.output) in by_map]
    with atomic_write(report, "the batch report") as tmp:
        tmp.write_text("".join(r.as_json() + "\n" for r in results), encoding="utf-8")
    return BatchSummary(results, len(jobs), interrupted)


def write_overview(
    outdir: Path, jobs: Sequence[Job], summary: BatchSummary, report: Path, seconds: float
) -> Path:
    """Write ``outdir/index.html`` (atomically), the overview page of this run: every
    finished log with its map's thumbnail (from the sidecars, so up-to-date maps have theirs
    too), and the logs an interrupted run did not finish."""
    from gridmap_cli.writers.overview import OverviewPage, overview_html

    finished = {r.map for r in summary.results}
    thumbnails = {}
    for job in jobs:
        if str(job.output) in finished:
            thumbnail = sidecar_thumbnail(job)
            if thumbnail is not None:
                thumbnails[str(job.output)] = thumbnail
    options = jobs[0].options if jobs else BatchOptions()
    build = options.build
    shown = [("pose", options.pose), ("mode", build.mode),
             ("cells", f"{build.resolution_m:g} m"),
             ("image", f"{options.map_mode} {options.image_format}")]  # fmt: skip
    if options.sensors:
        shown.append(("sensors", " ".join(options.sensors)))
    if options.start or options.end:
        shown.append(("window", f"{options.start or 'start'} to {options.end or 'end'}"))
    page = OverviewPage(
        folder=str(outdir),
        report=str(report),
        generated=time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
        seconds=seconds,
        resolution_m=build.resolution_m,
        version=__version__,
        total=summary.total,
        options=tuple(shown),
        interrupted=summary.interrupted,
        pending=tuple(str(job.log) for job in jobs if str(job.output) not in finished),
    )
    records = [dataclasses.asdict(r) for r in summary.results]
    target = outdir / OVERVIEW_NAME
    with atomic_write(target, "the batch overview") as tmp:
        tmp.write_text(overview_html(records, thumbnails, page), encoding="utf-8")
    return target


class BatchLock:
    """An exclusive, non-blocking lock on an output folder for the time of a batch run.

    Raises :class:`GridmapError` at entry when another run holds it, naming that run's pid.
    """

    def __init__(self, outdir: Path) -> None:
        self.path = outdir / LOCK_NAME
        self._handle: IO[str] | None = None

    def __enter__(self) -> BatchLock:
        handle = open(self.path, "a+", encoding="utf-8")
        try:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            holder = handle.read().strip() or "unknown"
            handle.close()
            raise GridmapError(
                f"{self.path.parent}: another gridmap batch is writing here (pid {holder}, "
                f"lock {self.path}); runs do not overlap, so this one stops"
            ) from None
        handle.seek(0)
        handle.truncate()
        handle.write(f"{os.getpid()}\n")
        handle.flush()
        self._handle = handle
        return self

    def __exit__(self, *exc: object) -> None:
        if self._handle is not None:
            with contextlib.suppress(OSError):
                self._handle.seek(0)
                self._handle.truncate()
            self._handle.close()  # closing releases the flock
            self._handle = None
