"""Fuzz the text readers: truncated files and flipped bytes of good inputs give either a log (or
description) or a :class:`GridmapError`, never another exception (the CLI's traceback).

The readers are called in-process on bytes in ``tmp`` files, so a few hundred examples run in
seconds; the CLI turns any GridmapError into one ``Error:`` line (``test_corpus.py``).
"""

from __future__ import annotations

import gzip
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gridmap_cli.errors import GridmapError
from gridmap_cli.mapping.mapfile import load_map
from gridmap_cli.readers import read_log
from gridmap_cli.robot import load_robot
from gridmap_cli.sim.path import load_path
from tests.corpus import generate as g

#: Examples per reader; GRIDMAP_FUZZ_EXAMPLES=5000 for a longer hunt.
EXAMPLES = int(os.environ.get("GRIDMAP_FUZZ_EXAMPLES", "200"))
PATH_YAML = "gridmap-path: 1\nwaypoints: [[0.5, 0.5], [1.5, 0.5], [1.5, 1.5]]\nspeed_m_s: 0.4\n"


def _read_log(path: Path) -> object:
    return read_log(path)


def _read_robot(path: Path) -> object:
    return load_robot(str(path))


def _read_world(path: Path) -> object:
    return load_map(path)


def _read_path(path: Path) -> object:
    return load_path(path)


GOOD: dict[str, tuple[str, bytes, Callable[[Path], object]]] = {
    "csv": ("log.csv", g.csv_text().encode(), _read_log),
    "aria": ("log.2d", g.aria_text().encode("latin-1"), _read_log),
    "carmen": ("run.log", g.carmen_text().encode(), _read_log),
    "robot-yaml": ("robot.yaml", g.robot_text().encode(), _read_robot),
    "aria-params": ("robot.p", (g.P_HEAD + g.P_RING).encode(), _read_robot),
    "world-yaml": ("world.yaml", g.WORLD_YAML.encode(), _read_world),
    "path-yaml": ("path.yaml", PATH_YAML.encode(), _read_path),
    # gzip text logs: damage to the compressed stream, not only to the text
    "csv-gz": ("log.csv.gz", gzip.compress(g.csv_text().encode(), mtime=0), _read_log),
    "carmen-gz": ("run.log.gz", gzip.compress(g.carmen_text().encode(), mtime=0), _read_log),
}


@st.composite
def damaged(draw: st.DrawFn, data: bytes) -> bytes:
    """``data`` truncated, with some bytes flipped, inserted or deleted."""
    out = bytearray(data[: draw(st.integers(0, len(data)))] if draw(st.booleans()) else data)
    for _ in range(draw(st.integers(0, 6))):
        if not out:
            break
        at = draw(st.integers(0, len(out) - 1))
        kind = draw(st.sampled_from(["flip", "insert", "delete"]))
        if kind == "flip":
            out[at] ^= draw(st.integers(1, 255))
        elif kind == "insert":
            out[at:at] = draw(st.binary(min_size=1, max_size=4))
        else:
            del out[at]
    return bytes(out)


def _check(kind: str, data: bytes, strict: bool = False) -> None:
    name, _, reader = GOOD[kind]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / name
        path.write_bytes(data)
        if kind == "world-yaml":
            # the world's image stays good; only its YAML is fuzzed
            rows = b"\x00" * 40 + (b"\x00" + b"\xfe" * 38 + b"\x00") * 38 + b"\x00" * 40
            (Path(folder) / "world.pgm").write_bytes(b"P5\n40 40\n255\n" + rows)
        try:
            reader(path)
        except GridmapError:
            if strict:
                raise


def test_the_good_inputs_read() -> None:
    for kind, (_, data, _) in GOOD.items():
        _check(kind, data, strict=True)


@pytest.mark.parametrize("kind", sorted(GOOD))
def test_damaged_text_inputs_never_raise_anything_but_gridmap_errors(kind: str) -> None:
    @settings(
        max_examples=EXAMPLES,
        deadline=None,
        suppress_health_check=[HealthCheck.too_slow],
    )
    @given(data=damaged(GOOD[kind][1]))
    def fuzz(data: bytes) -> None:
        _check(kind, data)

    fuzz()
