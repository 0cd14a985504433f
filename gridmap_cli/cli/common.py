"""What the commands share: one-line errors, progress bars, input and output checks, and the
options several commands take (topics and frames, sensor and time selection)."""

from __future__ import annotations

import contextlib
import functools
import json
import math
import numbers
import re
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ParamSpec, TypeVar

import click

from gridmap_cli.errors import GridmapError, UsageError, naming
from gridmap_cli.mapping.selection import EXCLUDE
from gridmap_cli.readers import STDIN_NAME, format_names, read_bytes, read_logs
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import parse_mount
from gridmap_cli.runs.settings import STDIO as STDIO
from gridmap_cli.runs.settings import check_input as check_input

if TYPE_CHECKING:
    from tqdm import tqdm

P = ParamSpec("P")
R = TypeVar("R")
F = TypeVar("F", bound=Callable[..., object])


class UsageFailure(click.ClickException):
    """A usage error reported on one line (click's UsageError would print the usage block)."""

    exit_code = 2


class Interrupted(click.ClickException):
    """Ctrl-C: exit 130 as shells expect (128 + SIGINT), one line, nothing half-written (every
    output is written to a temporary file and renamed only when complete)."""

    exit_code = 130

    def __init__(self, message: str = "no output was written or changed") -> None:
        super().__init__(f"interrupted (Ctrl-C); {message}")


def handle_errors(func: Callable[P, R]) -> Callable[P, R]:
    """Turn library errors into one-line ``Error:`` messages; tracebacks only with --debug."""

    @functools.wraps(func)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            with naming("flags"):  # errors name the command line's flags
                return func(*args, **kwargs)
        except KeyboardInterrupt as exc:
            if debug_enabled():
                raise
            raise Interrupted() from exc
        except GridmapError as exc:
            if debug_enabled():
                raise
            if isinstance(exc, UsageError):
                raise UsageFailure(one_line(str(exc))) from exc
            raise click.ClickException(one_line(str(exc))) from exc
        except (click.exceptions.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except MemoryError as exc:
            if debug_enabled():
                raise
            raise click.ClickException(
                "out of memory: the input is larger than this machine can map (--debug shows where)"
            ) from exc
        except Exception as exc:
            # unattended runs (cron) get one line and exit 1 even for what gridmap did not
            # foresee; the text says it is gridmap's fault, not the data's
            if debug_enabled():
                raise
            raise click.ClickException(
                f"internal error ({type(exc).__name__}: {one_line(str(exc))[:300]}); please "
                "report it with the output of --debug"
            ) from exc

    return wrapper


def one_line(text: str) -> str:
    """``text`` with its line breaks (and runs of spaces around them) folded into one space:
    every error is one line, whatever a library put in its message; numpy scalars' reprs
    (``np.float64(nan)``, from a tuple or ``!r``) as the plain numbers they are."""
    return plain_numbers(" ".join(part.strip() for part in text.splitlines() if part.strip()))


#: numpy 2's repr of a scalar: ``np.float64(1.5)``, ``np.int32(3)``, ``np.str_('a')``.
_NUMPY_REPR = re.compile(
    r"\bnp\.(?:float|int|uint|bool|str|bytes|complex|longdouble)\w*\(([^()]*)\)"
)

_NUMPY_BOOL = re.compile(r"\bnp\.(True|False)_")


def plain_numbers(text: str) -> str:
    """``text`` with every numpy scalar repr replaced by its value (``nan``, ``1.5``)."""
    return _NUMPY_BOOL.sub(r"\1", _NUMPY_REPR.sub(r"\1", text))


def debug_enabled() -> bool:
    """True when the command line asked for tracebacks (``gridmap --debug ...``)."""
    ctx = click.get_current_context(silent=True)
    root = ctx.find_root() if ctx is not None else None
    return bool(root is not None and root.obj and root.obj.get("debug"))


class _NoBar:
    """What a hidden progress bar does: nothing (and tqdm is not imported for it)."""

    def __enter__(self) -> _NoBar:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def update(self, n: int = 1) -> None:
        return None


def progress_bar(total: int, quiet: bool, desc: str) -> tqdm[Any] | _NoBar:
    # hidden when stderr is not a terminal (pipelines, cron) or with --quiet
    if quiet or not sys.stderr.isatty():
        return _NoBar()
    from tqdm import tqdm

    return tqdm(
        total=total,
        desc=desc,
        unit=" readings",
        unit_scale=True,
        file=sys.stderr,
        leave=False,
    )


def read_input(
    logs: Sequence[Path], log_format: str | None, options: ReadOptions | None = None
) -> RangeLog:
    """The log(s) to work on: files and folders as :func:`read_logs` reads them, or ``-``, a
    text log on standard input (``--format`` or its first bytes say which)."""
    if STDIO not in logs:
        return read_logs(logs, log_format, options)
    if len(logs) > 1:
        raise UsageError("- (standard input) is one log; it cannot be read with others")
    return read_bytes(sys.stdin.buffer.read(), STDIN_NAME, log_format, options)


@contextlib.contextmanager
def stdout_file(name: str) -> Iterator[Path]:
    """A file to write instead of ``-o -``: the writers write it (atomically, as always) in a
    temporary folder, and its bytes then go to standard output."""
    with tempfile.TemporaryDirectory(prefix="gridmap-") as folder:
        path = Path(folder) / name
        yield path
        stream = sys.stdout.buffer
        with open(path, "rb") as handle:
            shutil.copyfileobj(handle, stream)
        stream.flush()


def check_not_folder(output: Path) -> None:
    """An output named by a folder is a command-line mistake, said before anything else about
    the name (a rosbag2 folder is a log, never an output)."""
    if output != STDIO and output.is_dir():
        raise UsageError(f"{output} is a directory")


def check_output_folder(output: Path) -> None:
    if output == STDIO:
        return
    folder = output.parent
    if not folder.is_dir():
        raise GridmapError(f"{output}: directory {folder} does not exist")


def check_map_folder(output: Path) -> None:
    """A map's folder may be missing (``-o maps/run.png``, ``-f maps/run``: build makes it, as
    ``mkdir -p`` would, when it writes); a file where a folder should be is an error now."""
    if output == STDIO:
        return
    folder = output.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise GridmapError(f"{output}: {folder} is not a directory")


#: The options :func:`topic_options` adds, named as :class:`ReadOptions` fields.
TOPIC_FIELDS = (
    "odom_topic", "range_topics", "odom_frame", "base_frame", "pose_topic", "map_frame",
    "laser_mount",
)  # fmt: skip


def _laser_mount(
    ctx: click.Context, param: click.Parameter, value: str | None
) -> tuple[float, float, float] | None:
    try:
        return None if value is None else parse_mount(value)
    except UsageError as exc:
        raise click.BadParameter(str(exc).removeprefix(f"--laser-mount {value!r}: ")) from exc


def topic_options(func: Callable[..., R]) -> Callable[..., R]:
    """The topic and frame choices of ROS recordings (MCAP, bag, rosbag2), for the commands that
    read one: the command receives them together as ``topics``, a :class:`ReadOptions` without
    a robot (``dataclasses.replace(topics, robot=...)`` completes it)."""

    @functools.wraps(func)
    def gathered(*args: Any, **kwargs: Any) -> R:
        chosen = {name: kwargs.pop(name) for name in TOPIC_FIELDS}
        chosen["range_topics"] = tuple(chosen["range_topics"])
        return func(*args, topics=ReadOptions(**chosen), **kwargs)

    options = [
        click.option(
            "--odom-topic",
            help="ROS: pose topic to use as odometry, or /tf for its odom -> base transforms; "
            "default: the only Odometry/PoseStamped topic, else TF.",
        ),
        click.option(
            "--range-topic",
            "range_topics",
            multiple=True,
            help="ROS: range topic to map (repeatable); default: every Range, LaserScan, "
            "RosAria sonar and gridmap range topic.",
        ),
        click.option("--odom-frame", help="ROS: odometry frame in TF [default: odom]."),
        click.option(
            "--base-frame",
            help="ROS: the robot's base frame; default: the odometry's child frame, else the "
            "lowest frame TF moves below the odometry frame, else base_link.",
        ),
        click.option(
            "--pose-topic",
            help="ROS: the reference (corrected) pose topic for --pose global: PoseStamped, "
            "PoseWithCovarianceStamped (/amcl_pose) or Odometry; default: a ground_truth topic, "
            "else TF map -> base, else the one PoseWithCovarianceStamped topic.",
        ),
        click.option("--map-frame", help="ROS: the reference track's frame in TF [default: map]."),
        click.option(
            "--laser-mount",
            metavar="X,Y,YAW_DEG",
            callback=_laser_mount,
            help="ROS: the pose on the base frame (metres, degrees) of the recording's laser "
            "that TF does not mount, or of its one laser over TF's; its beams and range come "
            "from its LaserScan messages.",
        ),
    ]
    for option in reversed(options):
        gathered = option(gathered)
    return gathered


def force_option(help_text: str) -> Callable[[F], F]:
    """``--force``: what it lets the command overwrite."""
    return click.option("--force", is_flag=True, help=help_text)


def quiet_option(help_text: str) -> Callable[[F], F]:
    """``-q``/``--quiet``: what the command then leaves out."""
    return click.option("-q", "--quiet", is_flag=True, help=help_text)


def json_option(help_text: str) -> Callable[[F], F]:
    """``--json`` (the parameter ``as_json``): what the command prints as JSON."""
    return click.option("--json", "as_json", is_flag=True, help=help_text)


def logs_argument(func: F) -> F:
    """``LOG...``: one or more recordings, read as one run (checked by the readers, not click)."""
    return click.argument(
        "logs",
        metavar="LOG...",
        nargs=-1,
        required=True,
        type=click.Path(path_type=Path, readable=False),
    )(func)


def format_option(func: F) -> F:
    """``--format`` (the parameter ``log_format``): the reader to use, by name."""
    return click.option(
        "--format", "log_format", type=click.Choice(format_names()), help="Log format."
    )(func)


def selection_options(sensors: bool = True) -> Callable[[Callable[P, R]], Callable[P, R]]:
    """The choice of part of a log (``--sensors``, ``--start``, ``--end``), shared by the
    commands that read one; calibrate, comparing poses only, takes the window alone."""
    options = [
        click.option(
            "--start",
            metavar="TIME",
            help="Use the log from TIME on: seconds from the log's start (its first pose or "
            "reading), or an ISO 8601 time (2025-04-08T14:34:30Z; no offset means UTC).",
        ),
        click.option(
            "--end",
            metavar="TIME",
            help="Use the log up to TIME, not including it (as --start).",
        ),
    ]
    if sensors:
        options.insert(
            0,
            click.option(
                "--sensors",
                "sensor_patterns",
                multiple=True,
                metavar="PATTERN",
                help="Use the sensors whose names match this shell-style pattern ('sonar*', "
                f"'base_laser_link_*'); repeatable; '{EXCLUDE}PATTERN' leaves them out "
                "(quote it); default: all.",
            ),
        )

    def decorate(func: Callable[P, R]) -> Callable[P, R]:
        for option in reversed(options):
            func = option(func)
        return func

    return decorate


def warn(notes: tuple[str, ...], quiet: bool = False) -> None:
    if not quiet:
        for note in notes:
            click.echo(f"Warning: {one_line(note)}", err=True)


def _plain(value: Any) -> Any:
    """``value`` with floats at 12 significant digits (54.02, not 54.01999999999933: the noise
    of sums of decimals) and NaN/inf as null; numpy scalars and tuples become JSON's own."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        number = float(value)
        return float(f"{number:.12g}") if math.isfinite(number) else None
    return value


def json_text(doc: Any) -> str:
    """The JSON every ``--json`` prints: indented, floats without binary noise, no NaN."""
    return json.dumps(_plain(doc), indent=2, allow_nan=False)
