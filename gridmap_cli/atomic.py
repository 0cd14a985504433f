"""Write outputs so that a reader never sees a half-written file.

Each output is written to a hidden temporary file beside its target (same directory, so the final
``os.replace`` is a rename within one file system, which POSIX makes atomic) and renamed over the
target only when the writing code finished without an exception. On any exception the temporary
files are deleted and the exception propagates; the targets are left as they were. A writer
killed outright (SIGKILL) cannot delete them: the next writer of the same target does
(:func:`clean_leftovers`).

Each target is replaced by one ``os.replace``, never removed first, so at every instant it holds
either its old or its new content, even when the process dies between two renames.

:func:`atomic_outputs` does the same for several files that only make sense together (a map image
and its YAML): none of them is renamed unless the whole block succeeded, and if one of the final
renames fails, the renames already done are undone.
"""

from __future__ import annotations

import contextlib
import os
import re
import secrets
import shutil
from collections.abc import Iterator, Sequence
from pathlib import Path

from gridmap_cli.errors import GridmapError

#: How many random names to try before giving up on creating a temporary file; a clash of 32
#: random bits with a leftover file is already unlikely, several in a row mean something else.
_NAME_ATTEMPTS = 16


def _temp_path_for(target: Path, tag: str) -> Path:
    """Create (empty, exclusively) and return a hidden file beside ``target``.

    The name is ``.<name>.<tag>-<pid>-XXXXXXXX<suffix>``: hidden so directory listings and globs
    such as ``*.pgm`` skip it, ending in the target's suffix so that libraries that choose a
    format from the file name (Pillow) write the same format as they would to the target, and
    holding the writer's process id so that a later run can tell a crashed writer's leftovers
    (:func:`clean_leftovers`) from a live writer's files.
    """
    for _ in range(_NAME_ATTEMPTS):
        candidate = target.with_name(
            f".{target.name}.{tag}-{os.getpid()}-{secrets.token_hex(4)}{target.suffix}"
        )
        try:
            # 0o666 filtered by the umask, so the final file gets the permissions a plain
            # open() would have given it (tempfile.mkstemp would force 0o600).
            fd = os.open(candidate, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        os.close(fd)
        return candidate
    raise FileExistsError(f"could not create a temporary file beside {target}")


def _leftover_pattern(target: Path) -> re.Pattern[str]:
    # this module's names for ``target``, current (with a pid) and earlier (without one)
    return re.compile(
        rf"\.{re.escape(target.name)}\.(?:tmp|bak)-(?:(\d+)-)?[0-9a-f]{{8}}"
        rf"{re.escape(target.suffix)}"
    )


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, OSError):
        return True  # someone else's live process, or not ours to judge: leave its files
    return True


def clean_leftovers(target: Path) -> list[Path]:
    """Delete the temporary and backup files an earlier writer of ``target`` left when it was
    killed (SIGKILL, power loss) between creating them and renaming or discarding them.

    Only this module's own names for ``target`` are touched (``.<name>.tmp-<pid>-XXXXXXXX
    <suffix>`` and ``.bak-``), and only those whose process is gone, so a writer running now
    keeps its files. Returns the files deleted.
    """
    folder = target.parent
    pattern = _leftover_pattern(target)
    removed: list[Path] = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        match = pattern.fullmatch(entry.name)
        if match is None or (match.group(1) is not None and _alive(int(match.group(1)))):
            continue
        with contextlib.suppress(OSError):
            os.unlink(entry.path)
            removed.append(Path(entry.path))
    return removed


def _fsync_file(path: Path) -> None:
    # Without this a crash shortly after the rename can leave the target empty on file systems
    # that reorder metadata and data writes.
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_directory(folder: Path) -> None:
    # Makes the rename itself durable; not every platform lets a directory be opened, and losing
    # only durability (not atomicity) there is acceptable.
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _discard(paths: Sequence[Path]) -> None:
    for path in paths:
        with contextlib.suppress(OSError):
            path.unlink(missing_ok=True)


@contextlib.contextmanager
def atomic_output(path: Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it over ``path`` if the block succeeds.

    The temporary file exists (empty) when the block starts; the block writes it by name (for
    example ``image.save(tmp)`` or ``open(tmp, "w")``). On any exception, including
    ``KeyboardInterrupt``, the temporary file is deleted, ``path`` is untouched and the
    exception propagates.
    """
    with atomic_outputs([path]) as (tmp,):
        yield tmp


@contextlib.contextmanager
def atomic_write(path: Path, what: str) -> Iterator[Path]:
    """:func:`atomic_output`, with an ``OSError`` in the block (or in the final rename) raised as
    :class:`GridmapError` ``"<path>: cannot write <what>: <reason>"``, ``what`` like ``"the log"``.
    """
    try:
        with atomic_output(path) as tmp:
            yield tmp
    except OSError as exc:
        raise GridmapError(f"{path}: cannot write {what}: {exc.strerror or exc}") from exc


def _backup(target: Path) -> Path | None:
    """A hidden second name (or copy) for an existing regular file, so it can be restored."""
    if not target.is_file():
        return None
    backup = _temp_path_for(target, "bak")
    try:
        backup.unlink()
        try:
            # a hard link costs no copying and leaves the target itself in place
            os.link(target, backup)
        except OSError:
            shutil.copy2(target, backup)
    except BaseException:
        _discard([backup])
        raise
    return backup


@contextlib.contextmanager
def atomic_outputs(paths: Sequence[Path]) -> Iterator[list[Path]]:
    """Yield temporary paths for several outputs; rename them all only if the block succeeds.

    ``paths`` are the targets (distinct); the yielded list holds one temporary path per target,
    in the same order, each in its target's directory. After the block, targets are replaced one
    by one in order; if a replace fails (say a target turned out to be a directory), the targets
    already replaced are restored to their previous content (or removed if they did not exist)
    before the error propagates, so the set of outputs is either all new or all as it was.
    """
    targets = [Path(p) for p in paths]
    if len({t.resolve() for t in targets}) != len(targets):
        raise ValueError(f"the same output appears twice in {[str(t) for t in targets]}")
    for target in targets:
        clean_leftovers(target)
    temps: list[Path] = []
    try:
        for target in targets:
            temps.append(_temp_path_for(target, "tmp"))
        yield list(temps)
        for tmp in temps:
            _fsync_file(tmp)
    except BaseException:
        _discard(temps)
        raise
    _commit(temps, targets)


def _commit(temps: Sequence[Path], targets: Sequence[Path]) -> None:
    """Replace each target by its temporary file; undo every replace if any one fails."""
    done: list[tuple[Path, Path | None]] = []
    backups: list[Path] = []
    try:
        for tmp, target in zip(temps, targets, strict=True):
            backup = _backup(target)
            if backup is not None:
                backups.append(backup)
            os.replace(tmp, target)
            done.append((target, backup))
    except BaseException:
        for target, backup in reversed(done):
            with contextlib.suppress(OSError):
                if backup is not None:
                    os.replace(backup, target)
                else:
                    target.unlink(missing_ok=True)
        _discard(list(temps) + backups)
        raise
    _discard(backups)
    for folder in {t.parent for t in targets}:
        _fsync_directory(folder)
