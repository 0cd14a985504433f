"""The same recording given twice: refused, not merged.

Several ROS recordings given together are merged into one, so a recording given twice (the same
file, under two names, or a copy of it) would count each of its readings twice: evidence the
map does not have. ``build --fuse`` refuses the same; a recording is the same by its resolved
path, else by its content (sizes first, so that only files of equal size are hashed).
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

from gridmap_cli.errors import UsageError

_HASH_BLOCK = 1 << 20


def _files(path: Path) -> list[Path]:
    """The files a recording is made of: itself, or a folder's (rosbag2), in name order."""
    return sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]


def _size(path: Path) -> int:
    return sum(p.stat().st_size for p in _files(path))


def _digest(path: Path) -> str:
    digest = hashlib.sha256()
    for part in _files(path):
        if path.is_dir():
            digest.update(str(part.relative_to(path)).encode() + b"\0")
        with open(part, "rb") as handle:
            while block := handle.read(_HASH_BLOCK):
                digest.update(block)
    return digest.hexdigest()


def refuse_repeats(paths: Sequence[Path]) -> None:
    """Raise :class:`UsageError` when two of ``paths`` (recording files or rosbag2 folders)
    are the same recording: the same resolved path, or the same content."""
    seen: dict[Path, Path] = {}
    for path in paths:
        real = path.resolve()
        if real in seen:
            raise _twice(seen[real], path, "the same file")
        seen[real] = path
    by_size: dict[int, list[Path]] = {}
    for path in seen.values():
        by_size.setdefault(_size(path), []).append(path)
    for group in by_size.values():
        digests: dict[str, Path] = {}
        for path in group if len(group) > 1 else ():
            digest = _digest(path)
            if digest in digests:
                raise _twice(digests[digest], path, "the same content")
            digests[digest] = path


def _twice(first: Path, again: Path, how: str) -> UsageError:
    return UsageError(
        f"{again}: {how} as {first}: a recording given twice would count its evidence double "
        "(give it once)"
    )
