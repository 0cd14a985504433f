"""gzip bombs fail while decompressing, with one line and bounded memory (issue 21): gigabytes of
NULs, one endless line, on build, inspect and standard input alike.

The bombs are concatenated gzip members of one compressed piece, written by streaming: a few MB
on disk for gigabytes decompressed."""

from __future__ import annotations

import gzip
import tracemalloc
from pathlib import Path

import pytest
from click.testing import CliRunner

from gridmap_cli.cli import cli
from gridmap_cli.limits import MAX_LINE_CHARS
from gridmap_cli.readers.text.compressed import decompress_bytes
from tests.helpers import names

PEAK_BYTES = 48 * 2**20
MEMBER_BYTES = 64 * 2**20


def bomb(path: Path, fill: bytes, members: int, head: bytes = b"") -> Path:
    """``head`` then ``members`` x 64 MiB of ``fill`` repeated, as gzip members."""
    piece = gzip.compress(fill * (MEMBER_BYTES // len(fill)), compresslevel=9)
    with open(path, "wb") as handle:
        handle.write(gzip.compress(head))
        for _ in range(members):
            handle.write(piece)
    return path


def refused(tmp_path: Path, args: list[str], data: bytes | None = None) -> tuple[str, int]:
    before = names(tmp_path)
    tracemalloc.start()
    try:
        result = CliRunner().invoke(cli, args, input=data)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert result.exit_code == 1, result.output
    assert result.stderr.count("\n") == 1, result.stderr
    assert names(tmp_path) == before
    return result.stderr, peak


HEAD = b"# CARMEN Logfile\nODOM 0 0 0 0 0 0 1.0 host 1.0\n"
BOMBS = {
    "nuls-4GiB": (b"\0", 64, b""),  # 4 GiB of NULs, no line break
    "line-2GiB": (b"FLASER 1 " * 8, 32, HEAD),  # a 2 GiB third line
}


@pytest.mark.parametrize("kind", BOMBS)
@pytest.mark.parametrize("command", ["build", "inspect"])
def test_a_gzip_bomb_is_one_line_and_bounded(tmp_path: Path, kind: str, command: str) -> None:
    fill, members, head = BOMBS[kind]
    src = tmp_path / "src"
    src.mkdir()
    log = bomb(src / "bomb.log.gz", fill, members, head)
    assert log.stat().st_size < 8 * 2**20
    args = [command, str(log)] + (["-o", str(tmp_path / "m.png")] if command == "build" else [])
    err, peak = refused(tmp_path, args)
    line = head.count(b"\n") + 1
    assert err.startswith(f"Error: {log}:{line}: line longer than {MAX_LINE_CHARS:,} characters")
    assert peak < PEAK_BYTES


def test_a_gzip_bomb_on_standard_input(tmp_path: Path) -> None:
    data = bomb(tmp_path / "b.gz", b"\0", 16).read_bytes()
    (tmp_path / "b.gz").unlink()
    err, peak = refused(tmp_path, ["build", "-", "-o", str(tmp_path / "m.png")], data)
    assert err.startswith("Error: <stdin>:1: line longer than")
    assert peak < PEAK_BYTES + 2 * len(data)  # the compressed input is held


@pytest.mark.parametrize("ending", [b"\n", b"\r\n", b"\r"])
def test_long_logs_with_short_lines_decompress_whole(ending: bytes) -> None:
    text = (b"ODOM 0 0 0 0 0 0 1.0 host 1.0" + ending) * 200_000  # 6 MB, lines of 30 bytes
    assert decompress_bytes(gzip.compress(text) + gzip.compress(text), "x") == text * 2


def test_a_truncated_member_is_one_line(tmp_path: Path) -> None:
    data = gzip.compress(b"ODOM 0 0 0 0 0 0 1.0 host 1.0\n" * 1000)
    with pytest.raises(Exception, match="truncated"):
        decompress_bytes(data[: len(data) // 2], "x")
