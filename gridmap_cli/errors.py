"""One exception tree for everything gridmap can refuse or fail at.

Each exception formats its own message from fields, so the CLI only prints ``str(err)`` and
chooses the exit code: :class:`UsageError` subclasses are the user's command line (exit 2),
everything else is bad data or a runtime failure (exit 1).
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Iterator
from pathlib import Path


class GridmapError(Exception):
    """Root of every error gridmap raises on purpose."""

    def __reduce__(self) -> tuple[object, ...]:
        # rebuilt from its fields and message, not by calling the class again with the message
        # alone (the subclasses' constructors take fields): an error raised in a worker process
        # (Dask, multiprocessing) reaches the caller as the same error
        return _rebuilt, (type(self), str(self), dict(self.__dict__))


def _rebuilt(cls: type[GridmapError], message: str, fields: dict[str, object]) -> GridmapError:
    """An error of ``cls`` with ``message`` and its ``fields``, its constructor not called."""
    err = cls.__new__(cls)
    Exception.__init__(err, message)
    err.__dict__.update(fields)
    return err


class UsageError(GridmapError):
    """The command line asks for something that cannot be done (exit code 2)."""


class InputFileError(GridmapError):
    """A file is broken: the message names the file and, where known, the line and column.

    Formats as ``path:line: detail`` (``path: detail`` without a line).
    """

    def __init__(
        self, path: str | Path, detail: str, line: int | None = None, column: str | None = None
    ) -> None:
        self.path = str(path)
        self.detail = detail
        self.line = line
        self.column = column
        super().__init__(str(self))

    def __str__(self) -> str:
        where = self.path if self.line is None else f"{self.path}:{self.line}"
        what = self.detail if self.column is None else f"column '{self.column}': {self.detail}"
        return f"{where}: {what}"


class DamagedAtError(InputFileError):
    """A binary file is damaged at a byte offset: formats as ``path: byte N: detail``."""

    def __init__(self, path: str | Path, offset: int, detail: str) -> None:
        self.offset = offset
        super().__init__(path, f"byte {offset}: {detail}")


class NotRecordingFolderError(InputFileError):
    """A folder given as one log that holds no rosbag2 recording (a folder of logs, say)."""


class MixedLogsError(UsageError):
    """Several logs to read as one recording, and one of them is not a ROS recording."""


class UnknownFormatError(UsageError):
    """No reader claims the file: not the same thing as a file that is broken."""

    def __init__(self, path: str | Path, known: str, sniffed: str = "") -> None:
        self.path = str(path)
        self.known = known
        what = f": {sniffed}" if sniffed else ""
        super().__init__(f"{self.path}: not a log format gridmap reads{what} (known: {known})")


class RobotDescriptionError(InputFileError):
    """A robot description (YAML or ARIA .p) is malformed or inconsistent."""


class UnknownRobotError(UsageError):
    """``--robot`` names neither a preset nor an existing file."""

    def __init__(self, name: str, presets: list[str]) -> None:
        self.name = name
        super().__init__(
            f"unknown robot '{name}': not a preset ({', '.join(presets)}) and no such file"
        )


class OutputExistsError(GridmapError):
    """The output exists and ``--force`` was not given."""

    def __init__(self, path: str | Path) -> None:
        self.path = str(path)
        super().__init__(f"{self.path} exists (use {given('force', 'True')} to overwrite)")


class MapSizeError(GridmapError):
    """The data spans more cells than a map can sensibly hold (usually absurd coordinates)."""


class SimulationSizeError(GridmapError):
    """A simulation would sample more poses or readings than memory can sensibly hold."""


class NoDataError(GridmapError):
    """The log holds nothing that can be mapped."""


#: How an error names what the caller gave: "arguments" (a Python caller) or "flags" (the
#: command line, which sets it for the time of a command; :func:`naming`).
_NAMING: contextvars.ContextVar[str] = contextvars.ContextVar("gridmap_naming", default="arguments")


@contextlib.contextmanager
def naming(style: str) -> Iterator[None]:
    """Errors raised inside name what the caller gave as ``style`` says: "flags" (``--pose
    slam``) or "arguments" (``pose='slam'``)."""
    token = _NAMING.set(style)
    try:
        yield
    finally:
        _NAMING.reset(token)


#: Flags not spelt as their argument's name with dashes.
_FLAGS = {"odometry_coefficients": "--odometry-coefficient"}


def given(name: str, value: str | None = None) -> str:
    """What the caller gave, named for them: ``given("pose", "slam")`` is ``--pose slam`` on the
    command line and ``pose='slam'`` from Python; without a value, the flag or the argument's
    name alone (``--robot``, ``robot``); the value ``"True"`` is a flag alone (``--force``,
    ``force=True``)."""
    if _NAMING.get() == "flags":
        flag = _FLAGS.get(name, "--" + name.replace("_", "-"))
        return flag if value in (None, "True") else f"{flag} {value}"
    if value == "True":
        return f"{name}=True"
    return name if value is None else f"{name}={value!r}"


def naming_style() -> str:
    """The style errors name what the caller gave in here ("flags" or "arguments"): a job run
    in another process takes it along."""
    return _NAMING.get()
