"""Start-up: a CSV build imports none of the heavy optional machinery (issue 10's lazy imports)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from gridmap_cli import readers
from gridmap_cli.readers.ros.bag import log as bag_log
from gridmap_cli.readers.ros.mcap import channels as mcap_channels
from gridmap_cli.readers.text import carmen_log

SAMPLES = Path(__file__).resolve().parents[1] / "samples"

_PROBE = """\
import sys
from gridmap_cli.cli import cli
try:
    cli(sys.argv[1:], prog_name="gridmap")
except SystemExit as exc:
    assert exc.code == 0, exc.code
print(" ".join(sorted(sys.modules)))
"""

HEAVY = ("mcap", "mcap_ros1", "mcap_ros2", "rosbags", "scipy", "matplotlib", "tqdm")


def _modules_after(*args: str) -> set[str]:
    out = subprocess.run(
        [sys.executable, "-c", _PROBE, *args], capture_output=True, text=True, check=True
    )
    return set(out.stdout.split())


def test_a_csv_build_imports_no_decoder_plotting_or_scipy(tmp_path: Path) -> None:
    modules = _modules_after(
        "build", str(SAMPLES / "corridor_loop.csv"), "-o", str(tmp_path / "m.png"), "-q"
    )
    assert "gridmap_cli.readers.text.csv_log" in modules
    loaded = {m.split(".")[0] for m in modules} & set(HEAVY)
    assert not loaded
    assert not {m for m in modules if m.startswith(("gridmap_cli.readers.ros", "gridmap_cli.sim"))}
    # nor what only batch runs, scan matching or --draw-path use, nor numpy.ma (np.unique
    # loads it); the compiled kernels are there
    assert not modules & {
        "gridmap_cli.runs.batch", "gridmap_cli.poses.correction.scan_match",
        "gridmap_cli.writers.preview", "numpy.ma",
    }  # fmt: skip
    assert "gridmap_cli.mapping.models._ckernels" in modules


def test_version_imports_no_command() -> None:
    modules = _modules_after("--version")
    assert not {m for m in modules if m.startswith("gridmap_cli.cli.")}


def test_the_registry_sniffs_with_the_readers_own_constants() -> None:
    assert readers.MCAP_MAGIC == mcap_channels.MAGIC
    assert readers.BAG_MAGIC == bag_log.BAG_MAGIC
    assert readers.ROSBAG2_METADATA == bag_log.ROSBAG2_METADATA
    assert readers.CARMEN_EXTENSIONS == carmen_log.EXTENSIONS
    assert readers.CARMEN_WEAK_EXTENSIONS == carmen_log.WEAK_EXTENSIONS
