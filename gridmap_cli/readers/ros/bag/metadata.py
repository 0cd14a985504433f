"""A rosbag2 folder's ``metadata.yaml``, read and checked against the files it names.

What the metadata says (storage, compression) decides how the files are read; a metadata file
that says zstd over a plain sqlite file, or sqlite3 over an MCAP file, would otherwise reach the
readers as a decompression or database error with no word of the real cause. Each file is
checked by its first bytes, and a message-compressed sqlite3 bag by its first message.
"""

from __future__ import annotations

import contextlib
import sqlite3
from dataclasses import dataclass
from pathlib import Path

import yaml

from gridmap_cli.errors import InputFileError
from gridmap_cli.limits import read_settings_text
from gridmap_cli.yamlfile import yaml_problem

#: The file naming a rosbag2 folder's storage, files and topics.
ROSBAG2_METADATA = "metadata.yaml"
SQLITE_MAGIC = b"SQLite format 3\x00"
MCAP_MAGIC = b"\x89MCAP0\r\n"
ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
STORAGES = ("sqlite3", "mcap")
#: rosbag2's compression modes (``none`` is written as such or as an empty string).
MODES = ("none", "file", "message")


@dataclass(frozen=True)
class Rosbag2Metadata:
    """What ``metadata.yaml`` says: ``storage`` (sqlite3 or mcap), the ``files`` (relative to
    the folder) and the ``compression`` mode (none, file or message; always zstd)."""

    path: Path
    storage: str
    files: tuple[str, ...]
    compression: str


def read_metadata(folder: Path) -> Rosbag2Metadata:
    """Read and check ``folder``'s ``metadata.yaml``. Raises :class:`InputFileError` naming the
    metadata file (or a file it names) for unreadable or invalid YAML, an unknown storage or
    compression, a missing file, and files whose bytes contradict the metadata."""
    meta_path = folder / ROSBAG2_METADATA
    try:
        meta = yaml.safe_load(read_settings_text(meta_path, "rosbag2 metadata"))
        info = meta["rosbag2_bagfile_information"]
        storage = str(info.get("storage_identifier", "") or "sqlite3")
        files = tuple(str(f) for f in info.get("relative_file_paths") or [])
        mode = str(info.get("compression_mode", "") or "none").lower()
        compression_format = str(info.get("compression_format", "") or "")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputFileError(
            meta_path, f"cannot read: {getattr(exc, 'strerror', None) or exc}"
        ) from exc
    except yaml.YAMLError as exc:
        line, problem = yaml_problem(exc)
        raise InputFileError(meta_path, f"not a rosbag2 metadata file: {problem}", line) from exc
    except (KeyError, TypeError, AttributeError) as exc:
        raise InputFileError(
            meta_path, f"not a rosbag2 metadata file ({type(exc).__name__}: {exc})"
        ) from exc
    if storage not in STORAGES:
        raise InputFileError(
            meta_path, f"unknown rosbag2 storage '{storage}' (gridmap reads sqlite3 and mcap)"
        )
    if mode not in MODES:
        raise InputFileError(
            meta_path, f"unknown compression_mode '{mode}' (rosbag2 writes none, file or message)"
        )
    if mode != "none" and compression_format.lower() != "zstd":
        raise InputFileError(
            meta_path,
            f"compression_format '{compression_format}' with compression_mode {mode}: "
            "rosbag2 compresses with zstd, and gridmap reads only that",
        )
    missing = [f for f in files if not (folder / f).is_file()]
    if missing or not files:
        kind = "MCAP" if storage == "mcap" else "sqlite3"
        raise InputFileError(
            meta_path, f"names {kind} files that are not in the folder: {', '.join(missing)}"
        )
    out = Rosbag2Metadata(meta_path, storage, files, mode)
    for name in files:
        _check_file(out, folder / name)
    if mode == "message" and storage == "sqlite3":
        _check_first_message(out, folder / files[0])
    return out


def _kind(head: bytes) -> str | None:
    if head.startswith(ZSTD_MAGIC):
        return "zstd-compressed data"
    if head.startswith(SQLITE_MAGIC):
        return "an sqlite3 database"
    if head.startswith(MCAP_MAGIC):
        return "an MCAP file"
    return None  # damaged or something else: its reader says what is wrong


def _check_file(meta: Rosbag2Metadata, path: Path) -> None:
    try:
        with open(path, "rb") as handle:
            head = handle.read(16)
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from exc
    kind = _kind(head)
    if meta.compression == "file":
        if meta.storage == "mcap":
            raise InputFileError(
                meta.path,
                "zstd-compressed MCAP storage files (compression_mode file) are not read by "
                f"gridmap; decompress them (zstd -d {path.name}) and fix the metadata",
            )
        if kind is not None and kind != "zstd-compressed data":
            raise InputFileError(
                path,
                f"{meta.path.name} says compression_mode file (zstd), but this is {kind}, "
                "not compressed",
            )
        return
    if meta.storage == "mcap" and meta.compression == "message":
        raise InputFileError(
            meta.path,
            "rosbag2 message compression over MCAP storage is not read by gridmap (MCAP "
            "compresses its chunks itself)",
        )
    expected = "an sqlite3 database" if meta.storage == "sqlite3" else "an MCAP file"
    if kind is not None and kind != expected:
        said = f"storage {meta.storage}" + (
            ", no compression" if kind == "zstd-compressed data" else ""
        )
        raise InputFileError(path, f"{meta.path.name} says {said}, but this is {kind}")


def _check_first_message(meta: Rosbag2Metadata, path: Path) -> None:
    """Message compression: the first message must be a zstd frame."""
    try:
        with contextlib.closing(
            sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
        ) as db:
            row = db.execute(
                "SELECT topics.name, messages.data FROM messages JOIN topics "
                "ON messages.topic_id = topics.id ORDER BY messages.id LIMIT 1"
            ).fetchone()
    except sqlite3.Error:
        return  # a damaged database: the reader says so
    if row is not None and not bytes(row[1]).startswith(ZSTD_MAGIC):
        raise InputFileError(
            path,
            f"message 1 of {row[0]}: {meta.path.name} says compression_mode message (zstd), "
            "but the message is not zstd-compressed",
        )
