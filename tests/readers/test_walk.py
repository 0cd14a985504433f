"""The compiled record walks (gridmap_cli/readers/ros/_cwalk.c) find the same first unsound record
as the Python walks of the integrity checks, on sound chunks and on damaged ones."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from gridmap_cli import extensions
from gridmap_cli.errors import DamagedAtError
from gridmap_cli.readers.ros.bag import integrity as bag_integrity
from gridmap_cli.readers.ros.mcap import integrity as mcap_integrity
from gridmap_cli.readers.ros.walk import compiled_walk


@pytest.fixture
def walk(monkeypatch: pytest.MonkeyPatch) -> object:
    monkeypatch.setattr(extensions, "KERNELS", "compiled")  # built by the dev install: no skip
    return compiled_walk()


def _mcap_chunk(rng: np.random.Generator, n: int) -> bytes:
    out = b""
    for _ in range(n):
        opcode = int(rng.choice(list(mcap_integrity._IN_CHUNK)))
        size = int(rng.integers(22, 60)) if opcode == mcap_integrity._MESSAGE else 10
        out += bytes([opcode]) + struct.pack("<Q", size) + rng.bytes(size)
    return out


def _mcap_reference(data: bytes) -> int:
    for offset, opcode, length, fits in mcap_integrity._records(data):
        if not fits or opcode not in mcap_integrity._IN_CHUNK:
            return offset
        if opcode == mcap_integrity._MESSAGE and length < mcap_integrity._MESSAGE_FIXED:
            return offset
    return -1


def _damaged(rng: np.random.Generator, data: bytes) -> list[bytes]:
    cases = [data[: int(rng.integers(0, len(data)))] for _ in range(20)]
    for _ in range(60):
        b = bytearray(data)
        b[int(rng.integers(0, len(b)))] = int(rng.integers(0, 256))
        cases.append(bytes(b))
    return cases


def test_mcap_walk_agrees_with_the_python_walk(walk: object) -> None:
    rng = np.random.default_rng(5)
    data = _mcap_chunk(rng, 40)
    assert walk.mcap_records(data, mcap_integrity._IN_CHUNK_BYTES, 5, 22) == -1  # type: ignore[attr-defined]
    found = set()
    for case in _damaged(rng, data):
        got = walk.mcap_records(case, mcap_integrity._IN_CHUNK_BYTES, 5, 22)  # type: ignore[attr-defined]
        assert got == _mcap_reference(case)
        found.add(got >= 0)
    assert found == {True, False}  # some damage is harmless to the structure, some is not


def _bag_record(fields: list[tuple[bytes, bytes]], data: bytes) -> bytes:
    header = b"".join(struct.pack("<I", len(k) + 1 + len(v)) + k + b"=" + v for k, v in fields)
    return struct.pack("<I", len(header)) + header + struct.pack("<I", len(data)) + data


def _bag_chunk(rng: np.random.Generator, n: int) -> bytes:
    out = b""
    for i in range(n):
        if i % 7 == 0:
            fields = [(b"op", b"\x07"), (b"conn", struct.pack("<I", i)), (b"topic", b"/sonar")]
        else:
            fields = [(b"conn", struct.pack("<I", 0)), (b"op", b"\x02"), (b"time", rng.bytes(8))]
        out += _bag_record(fields, rng.bytes(int(rng.integers(0, 40))))
    return out


def _bag_reference(data: bytes) -> tuple[int, list[int]]:
    """The first record the Python walk refuses (-1: none), and the non-message records
    before it."""
    bad = -1
    try:
        bag_integrity._records("x.bag", data, 0, "chunk")  # type: ignore[arg-type]
    except DamagedAtError as exc:
        bad = int(str(exc).split("byte ")[1].split(":")[0])
    sound = bag_integrity._records("x.bag", data[: bad if bad >= 0 else None], 0, "chunk")  # type: ignore[arg-type]
    return bad, [at for at, fields, _ in sound if fields[b"op"][0] != bag_integrity._MSG_DATA]


def test_bag_walk_agrees_with_the_python_walk(walk: object) -> None:
    rng = np.random.default_rng(9)
    data = _bag_chunk(rng, 50)
    known = bag_integrity._KNOWN_OPS_BYTES
    bad, others = walk.bag_records(data, known, 2)  # type: ignore[attr-defined]
    assert (bad, others) == _bag_reference(data)
    assert bad == -1 and len(others) == 8
    found = set()
    for case in _damaged(rng, data):
        bad, others = walk.bag_records(case, known, 2)  # type: ignore[attr-defined]
        ref_bad, ref_others = _bag_reference(case)
        assert bad == ref_bad
        assert others == ref_others
        found.add(bad >= 0)
    assert found == {True, False}
