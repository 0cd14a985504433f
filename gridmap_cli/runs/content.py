"""What a log holds, as a key: batch's sidecars and fuse's duplicate check both name a log by
the SHA-256 of its content, so the same file under two names is the same log; batch's key of a
map adds every option that changes the map (:func:`build_key`)."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

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


def build_key(content: str, options: Mapping[str, Any], version: str) -> str:
    """The key a map is built from: its log's :func:`content_hash`, every option that changes
    the map (``options``: plain JSON values, nested) and gridmap's version. JSON writes floats
    exactly (their shortest ``repr``), so equal options give one key and unequal ones two."""
    text = json.dumps({"content": content, "options": options, "gridmap": version},
                      sort_keys=True, default=str)  # fmt: skip
    return hashlib.sha256(text.encode()).hexdigest()
