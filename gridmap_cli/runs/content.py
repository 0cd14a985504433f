"""What a log holds, as a key: batch's sidecars and fuse's duplicate check both name a log by
the SHA-256 of its content, so the same file under two names is the same log."""

from __future__ import annotations

import hashlib
from pathlib import Path

_HASH_BLOCK = 1 << 20


def content_hash(log: Path) -> tuple[str, int]:
    """SHA-256 of a log's content and its size in bytes; a folder (rosbag2) hashes each file's
    relative name and content, in name order."""
    digest = hashlib.sha256()
    total = 0
    files = sorted(p for p in log.rglob("*") if p.is_file()) if log.is_dir() else [log]
    for path in files:
        if log.is_dir():
            digest.update(str(path.relative_to(log)).encode() + b"\0")
        with open(path, "rb") as handle:
            while block := handle.read(_HASH_BLOCK):
                digest.update(block)
                total += len(block)
    return digest.hexdigest(), total
