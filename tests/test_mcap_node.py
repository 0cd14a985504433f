"""A second MCAP implementation reads what gridmap writes: the TypeScript ``@mcap/core`` reader.

tests/node/validate_mcap.mjs reads each file with its indexed and its streaming reader (CRCs
validated) and prints the message count per topic. Runs when ``node`` is on the PATH and the
pinned packages are installed (``cd tests/node && npm ci``, which ``.ci/run`` does when npm
exists); skipped otherwise, except under CI (the ``CI`` environment variable set, as CI
services set it): there ``node`` without the packages fails, since it means the npm install
broke.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from tests.helpers import run

REPO = Path(__file__).resolve().parent.parent
NODE_DIR = REPO / "tests" / "node"
SCRIPT = NODE_DIR / "validate_mcap.mjs"
NODE = shutil.which("node")

PACKAGES = NODE_DIR / "node_modules" / "@mcap" / "core"


@pytest.fixture(autouse=True)
def node_and_packages() -> None:
    """Skip without node or tests/node's packages; under CI, fail when only the packages lack."""
    if NODE is None:
        pytest.skip("node is not on the PATH")
    if not PACKAGES.is_dir():
        message = f"node is installed but {PACKAGES} is not (cd tests/node && npm ci)"
        if os.environ.get("CI", "").lower() not in ("", "0", "false"):
            pytest.fail(f"{message}: under CI the npm install must have failed")
        pytest.skip(message)


def node_read(*paths: Path) -> tuple[int, list[dict[str, Any]], str]:
    assert NODE is not None
    done = subprocess.run(
        [NODE, str(SCRIPT), *map(str, paths)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.strip()]
    return done.returncode, lines, done.stderr


def python_counts(path: Path) -> dict[str, int]:
    """Message count per topic, counted message by message with the Python mcap reader."""
    counts: dict[str, int] = {}
    with path.open("rb") as handle:
        for _, channel, _ in make_reader(handle, validate_crcs=True).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return counts


def test_the_samples_read_alike_in_typescript() -> None:
    samples = [
        REPO / "samples" / "corridor_loop.mcap",
        REPO / "samples" / "corridor_loop_ros2.mcap",
    ]
    code, lines, err = node_read(*samples)
    assert code == 0, err
    assert [line["file"] for line in lines] == [str(p) for p in samples]
    for line, path in zip(lines, samples, strict=True):
        assert line["counts"] == python_counts(path)
        assert line["library"] == "gridmap-cli"
        assert line["metadata"] == ["gridmap"]
    assert lines[0]["profile"] == "" and lines[1]["profile"] == "ros2"
    assert lines[0]["counts"]["/range"] == 23488 and lines[1]["counts"]["/sonar"] == 23488


def test_fresh_files_with_a_laser_and_a_map_read_alike(tmp_path: Path) -> None:
    world = REPO / "samples" / "worlds" / "corridor_loop.yaml"
    path = REPO / "samples" / "paths" / "corridor_loop.yaml"
    outputs = []
    for encoding in ("json", "ros2"):
        out = tmp_path / f"laser_{encoding}.mcap"
        code, _, err = run(
            "simulate", str(world), str(path), "-o", str(out), "--robot", "p3at-lms200",
            "--encoding", encoding, "--duration", "1", "--quiet",
        )  # fmt: skip
        assert code == 0, err
        outputs.append(out)
    log = REPO / "samples" / "corridor_loop.csv"
    code, _, err = run("build", str(log), "-o", str(tmp_path / "map.mcap"), "-q")
    assert code == 0, err
    outputs.append(tmp_path / "map.mcap")
    code, lines, err = node_read(*outputs)
    assert code == 0, err
    for line, out in zip(lines, outputs, strict=True):
        assert line["counts"] == python_counts(out)
    # 1 s at 10 Hz: 10 stamps; 16 sonars + 181 laser beams as sensors, one scan per stamp
    assert lines[0]["counts"]["/sensors"] == 16 + 181
    assert lines[1]["counts"]["/scan"] == 10 and lines[1]["counts"]["/sonar"] == 160
    assert lines[2]["counts"] == {"/map": 1}


def test_a_wrong_crc_is_caught_in_typescript_too(tmp_path: Path) -> None:
    data = bytearray((REPO / "samples" / "corridor_loop.mcap").read_bytes())
    with (REPO / "samples" / "corridor_loop.mcap").open("rb") as handle:
        summary = make_reader(handle).get_summary()
    assert summary is not None
    # the uncompressed CRC of the first chunk: 33 bytes into the Chunk record
    data[summary.chunk_indexes[0].chunk_start_offset + 33] ^= 0xFF
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    code, lines, err = node_read(bad)
    assert code == 1 and lines == []
    assert err.startswith(f"{bad}: ") and "crc" in err.lower()
