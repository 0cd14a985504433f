"""``gridmap batch``: one map per log for unattended runs (cron), with build's map options."""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import click
from tqdm import tqdm

from gridmap_cli.cli.common import Interrupted, handle_errors, quiet_option
from gridmap_cli.cli.map_options import (
    error_samples_option,
    image_format_option,
    map_options,
)
from gridmap_cli.errors import GridmapError, UsageError
from gridmap_cli.robot import load_robot, preset_names
from gridmap_cli.runs.batch import (
    OVERVIEW_NAME,
    REPORT_NAME,
    BatchLock,
    BatchOptions,
    BatchSummary,
    JobResult,
    find_logs,
    plan_jobs,
    run_batch,
    write_overview,
)
from gridmap_cli.runs.executors import (
    EXECUTORS,
    Submit,
    check_dask,
    check_scheduler,
    dask_cluster,
    local_processes,
)
from gridmap_cli.runs.settings import MapOptions, map_settings
from gridmap_cli.writers.map_image import check_map_outputs

#: Maps named in the Ctrl-C line; more are counted.
NAMED_IN_INTERRUPT = 10


@click.command()
@click.argument("inputs", metavar="INPUTS...", nargs=-1, required=True)
@click.option(
    "-o",
    "--output",
    "outdir",
    required=True,
    type=click.Path(path_type=Path, file_okay=False),
    help="Folder for the maps (created if missing): LOG's map is <stem>.png (or --fmt) with "
    f"its YAML, and {OVERVIEW_NAME} shows them all.",
)
@image_format_option("Image format of every map [default: png].")
@map_options
@error_samples_option
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=1, show_default=True,
              help="Logs built at once, each in its own local process.")  # fmt: skip
@click.option(
    "--executor",
    type=click.Choice(EXECUTORS),
    default="local",
    show_default=True,
    help="Where the jobs run: local processes, or a Dask cluster (--scheduler).",
)
@click.option(
    "--scheduler",
    metavar="ADDRESS",
    help="Dask scheduler address (tcp://host:8786) for --executor dask.",
)
@click.option(
    "--report",
    type=click.Path(path_type=Path, dir_okay=False),
    help=f"JSON-lines report, one line per log [default: OUTDIR/{REPORT_NAME}].",
)
@quiet_option("No progress bar and no summary on stderr.")
@handle_errors
def batch(
    inputs: tuple[str, ...],
    outdir: Path,
    image_format: str | None,
    map_options: MapOptions,
    jobs: int,
    executor: str,
    scheduler: str | None,
    report: Path | None,
    quiet: bool,
) -> None:
    """Build one map per log of INPUTS into a folder, skipping logs whose map is up to date.

    INPUTS are log files, folders of logs (files with a log extension and rosbag2 folders) and
    globs (quote them; '**' recurses). The map options are build's. A map is up to date when
    its sidecar holds the hash of the log's content and of every option that changes the map;
    it is then left alone. A log that fails is reported and the batch goes on; the exit code is
    1 if any log failed. OUTDIR/index.html shows every map, its status and warnings, for a
    browser. Two batch runs never write one folder at once: the second stops at once with
    exit 1. A refused run writes nothing, not even OUTDIR.
    """
    started = time.perf_counter()
    options = _batch_options(image_format or "png", map_options)
    if executor == "dask":
        if scheduler is None:
            raise UsageError("--executor dask needs --scheduler ADDRESS (tcp://host:8786)")
        if jobs != 1:
            raise UsageError("--jobs is for local processes; a Dask cluster has its own workers")
        check_scheduler(scheduler)
        check_dask()
    elif scheduler is not None:
        raise UsageError("--scheduler applies to --executor dask")
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"{outdir}: not a folder")
    if not outdir.parent.is_dir():
        raise GridmapError(f"{outdir}: its parent folder {outdir.parent} does not exist")
    report_path = (report or outdir / REPORT_NAME).resolve()
    if report is not None and not report.parent.is_dir():
        raise GridmapError(f"--report {report}: its folder {report.parent} does not exist")
    logs = find_logs(inputs)
    outdir = outdir.resolve()
    planned = plan_jobs(logs, outdir, options)  # names clash: refused before the folder exists
    with _executor(scheduler, jobs) as submit:  # an unreachable scheduler: the same
        _make_folder(outdir)
        bar = tqdm(total=len(planned), desc="batch", unit=" logs", file=sys.stderr,
                   disable=quiet or not sys.stderr.isatty(), leave=False)  # fmt: skip

        def progress(result: JobResult) -> None:
            bar.update(1)
            if result.status == "failed" and not quiet:
                bar.clear()
                click.echo(f"Failed: {result.error}", err=True)

        with BatchLock(outdir), bar:
            summary = run_batch(planned, submit, report_path, progress)
            overview = write_overview(outdir, planned, summary, report_path,
                                      time.perf_counter() - started)  # fmt: skip
    if summary.interrupted:
        raise Interrupted(_interrupted_line(summary, report_path, overview, executor))
    if not quiet:
        click.echo(
            f"gridmap batch: {summary.count('built')} built, {summary.count('skipped')} up to "
            f"date, {summary.failed} failed of {len(planned)} logs -> {outdir} (overview: "
            f"{overview})",
            err=True,
        )
    if summary.failed:
        sys.exit(1)


def _batch_options(image_format: str, opts: MapOptions) -> BatchOptions:
    """Build's usage checks of the map options, and the options as every job takes them."""
    build = map_settings(opts)
    check_map_outputs(Path(f"map.{image_format}"), opts.map_mode, True)  # scale needs a PNG
    opts.selection()  # bad patterns and times before any work
    robot = opts.robot
    if robot is not None:
        load_robot(robot)  # a bad robot is a usage error before any log is read
        if robot not in preset_names():
            robot = str(Path(robot).resolve())
    return BatchOptions(build=build, robot=robot, log_format=opts.log_format, pose=opts.pose,
                        topics=opts.topics, sensors=opts.sensors, start=opts.start, end=opts.end,
                        map_mode=opts.map_mode, occupied=opts.occupied, free=opts.free,
                        image_format=image_format)  # fmt: skip


@contextlib.contextmanager
def _executor(scheduler: str | None, jobs: int) -> Iterator[Submit]:
    if scheduler is None:
        yield local_processes(jobs)
        return
    with dask_cluster(scheduler) as submit:
        yield submit


def _make_folder(outdir: Path) -> None:
    try:
        outdir.mkdir(exist_ok=True)
    except OSError as exc:
        raise GridmapError(f"{outdir}: cannot create the folder: {exc.strerror or exc}") from exc


def _interrupted_line(summary: BatchSummary, report: Path, overview: Path, executor: str) -> str:
    """What a Ctrl-C stopped and what it left: the finished logs, counted and named."""
    done = len(summary.results)
    built = [Path(r.map).name for r in summary.results if r.status == "built"]
    named = ", ".join(built[:NAMED_IN_INTERRUPT])
    if len(built) > NAMED_IN_INTERRUPT:
        named += f" and {len(built) - NAMED_IN_INTERRUPT} more"
    left = summary.total - done
    running = (
        "; Dask tasks already running may still write their maps whole"
        if executor == "dask" and left
        else ""
    )
    return (
        f"{done} of {summary.total} logs finished: {len(built)} built"
        + (f" ({named})" if built else "")
        + f", {summary.count('skipped')} up to date, {summary.failed} failed; the other "
        f"{left} maps were left as they were{running}; report {report}, overview {overview}"
    )
