"""``gridmap batch``: one map per log for unattended runs (cron)."""

from __future__ import annotations

import sys
from pathlib import Path

import click
from tqdm import tqdm

from gridmap_cli.cli.common import handle_errors
from gridmap_cli.cli.map_options import check_resolution
from gridmap_cli.errors import GridmapError, UsageError
from gridmap_cli.poses.sync import POSE_SOURCES
from gridmap_cli.readers import format_names
from gridmap_cli.robot import load_robot, preset_names
from gridmap_cli.runs.batch import (
    REPORT_NAME,
    BatchLock,
    BatchOptions,
    JobResult,
    find_logs,
    plan_jobs,
    run_batch,
)
from gridmap_cli.runs.executors import EXECUTORS, check_dask, dask_cluster, local_processes
from gridmap_cli.writers.map_image import MAP_MODES


@click.command()
@click.argument("inputs", metavar="INPUTS...", nargs=-1, required=True)
@click.option(
    "-o",
    "--output",
    "outdir",
    required=True,
    type=click.Path(path_type=Path, file_okay=False),
    help="Folder for the maps (created if missing): LOG's map is <stem>.png with its YAML.",
)
@click.option("--robot", help="Robot preset, robot YAML or ARIA .p for every log; default: "
              "each log's own '# robot:' line.")  # fmt: skip
@click.option("--format", "log_format", type=click.Choice(format_names()), help="Log format.")
@click.option("--resolution", type=float, default=0.05, show_default=True,
              help="Cell size in metres.")  # fmt: skip
@click.option("--pose", type=click.Choice(POSE_SOURCES), default="odometry", show_default=True,
              help="Map with the odometry or the log's global pose.")  # fmt: skip
@click.option("--map-mode", type=click.Choice(MAP_MODES), default="trinary", show_default=True,
              help="How occupancy is stored in the images.")  # fmt: skip
@click.option("--occupied", type=float, default=0.65, show_default=True,
              help="Probability at or above which a cell is occupied.")  # fmt: skip
@click.option("--free", type=float, default=0.25, show_default=True,
              help="Probability at or below which a cell is free.")  # fmt: skip
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
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary on stderr.")
@handle_errors
def batch(
    inputs: tuple[str, ...],
    outdir: Path,
    robot: str | None,
    log_format: str | None,
    resolution: float,
    pose: str,
    map_mode: str,
    occupied: float,
    free: float,
    jobs: int,
    executor: str,
    scheduler: str | None,
    report: Path | None,
    quiet: bool,
) -> None:
    """Build one map per log of INPUTS into a folder, skipping logs whose map is up to date.

    INPUTS are log files, folders of logs (files with a log extension and rosbag2 folders) and
    globs (quote them; '**' recurses). A map is up to date when its sidecar holds the hash of
    the log's content and of the options; it is then left alone. A log that fails is reported
    and the batch goes on; the exit code is 1 if any log failed. Two batch runs never write one
    folder at once: the second stops at once with exit 1.
    """
    if not (0.0 <= free < occupied <= 1.0):
        raise UsageError(f"need 0 <= --free < --occupied <= 1, got {free} and {occupied}")
    check_resolution(resolution)
    if executor == "dask":
        if scheduler is None:
            raise UsageError("--executor dask needs --scheduler ADDRESS (tcp://host:8786)")
        if jobs != 1:
            raise UsageError("--jobs is for local processes; a Dask cluster has its own workers")
        check_dask()
    elif scheduler is not None:
        raise UsageError("--scheduler applies to --executor dask")
    if robot is not None:
        load_robot(robot)  # a bad robot is a usage error before any log is read
        if robot not in preset_names():
            robot = str(Path(robot).resolve())
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"{outdir}: not a folder")
    if not outdir.parent.is_dir():
        raise GridmapError(f"{outdir}: its parent folder {outdir.parent} does not exist")
    logs = [log.resolve() for log in find_logs(inputs)]
    outdir.mkdir(exist_ok=True)
    outdir = outdir.resolve()
    options = BatchOptions(resolution_m=resolution, robot=robot, pose=pose, map_mode=map_mode,
                           occupied=occupied, free=free, log_format=log_format)  # fmt: skip
    planned = plan_jobs(logs, outdir, options)
    submit = dask_cluster(scheduler) if scheduler is not None else local_processes(jobs)
    bar = tqdm(total=len(planned), desc="batch", unit=" logs", file=sys.stderr,
               disable=quiet or not sys.stderr.isatty(), leave=False)  # fmt: skip

    def progress(result: JobResult) -> None:
        bar.update(1)
        if result.status == "failed" and not quiet:
            bar.clear()
            click.echo(f"Failed: {result.error}", err=True)

    with BatchLock(outdir), bar:
        summary = run_batch(planned, submit, report or outdir / REPORT_NAME, progress)
    if not quiet:
        click.echo(
            f"gridmap batch: {summary.count('built')} built, {summary.count('skipped')} up to "
            f"date, {summary.failed} failed of {len(planned)} logs -> {outdir}",
            err=True,
        )
    if summary.failed:
        sys.exit(1)
