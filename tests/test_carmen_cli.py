"""gridmap build and inspect on CARMEN logs, as a user meets them."""

from __future__ import annotations

import gzip
from pathlib import Path

import pytest
import yaml

from tests.helpers import names, run
from tests.readers.carmen_helpers import flaser, odom, write
from tests.readers.test_carmen_log import corrected_log
from tests.readers.test_carmen_real import DATA


def test_broken_line_is_one_error_line_and_nothing_written(tmp_path: Path) -> None:
    lines = corrected_log()
    lines[3] = lines[3].replace("FLASER 5 ", "FLASER 6 ", 1)
    log = tmp_path / "run.log.gz"
    log.write_bytes(gzip.compress(write(tmp_path, lines).read_bytes()))
    (tmp_path / "run.log").unlink()
    out = tmp_path / "map.png"
    code, stdout, stderr = run("build", str(log), "-o", str(out))
    assert code == 1 and stdout == ""
    assert stderr == (
        f"Error: {log}:7: FLASER: num_readings 6 means 17 fields (ranges, laser and robot pose, "
        "ipc_timestamp hostname logger_timestamp), found 16\n"
    )
    assert names(tmp_path) == {"run.log.gz"}


def test_corrupt_gzip_is_one_error_line(tmp_path: Path) -> None:
    log = tmp_path / "run.log.gz"
    log.write_bytes(b"\x1f\x8b\x08\x00 broken")
    code, _, stderr = run("build", str(log), "-o", str(tmp_path / "map.png"))
    assert code == 1 and stderr.startswith(f"Error: {log}: not a valid gzip file")
    assert stderr.count("\n") == 1 and names(tmp_path) == {"run.log.gz"}


def test_build_both_tracks_and_inspect(tmp_path: Path) -> None:
    lines = [*corrected_log(), flaser([1.0] * 5, (1.0, 0.1, 0.1), 2.0)]
    log = write(tmp_path, lines)
    for pose in ("odometry", "global"):
        code, _, stderr = run(
            "build", str(log), "-o", str(tmp_path / f"{pose}.png"), "--pose", pose
        )
        assert code == 0, stderr
    code, stdout, _ = run("inspect", str(log))
    assert code == 0
    assert "CARMEN log" in stdout
    assert "truth     reference track: the corrected poses of the 3 laser lines" in stdout
    assert "-> ready to build" in stdout


def test_mcap_flags_are_refused(tmp_path: Path) -> None:
    log = write(tmp_path, [odom((0, 0, 0), 1.0), flaser([1.0] * 5, (0, 0, 0), 1.0)])
    code, _, stderr = run("build", str(log), "-o", str(tmp_path / "m.png"), "--odom-topic", "/odom")
    assert code == 2 and "applies to ROS recordings (MCAP, bag, rosbag2), not to CARMEN" in stderr


@pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/carmen is not present")
def test_intel_corrected_map_is_the_lab(tmp_path: Path) -> None:
    out = tmp_path / "intel.png"
    code, _, stderr = run("build", str(DATA / "intel-corrected.log.gz"), "-o", str(out),
                          "--pose", "global")  # fmt: skip
    assert code == 0, stderr
    # every beam of the 910 scans, the 4,172 without echo too (free space up to the cap)
    assert f"{910 * 180:,} of {910 * 180:,} readings mapped" in stderr
    # the lab is about 35 m square; drifting odometry would smear it over twice that
    width_cells, height_cells = (int(v) for v in stderr.split(" cells")[0].split()[-3::2])
    meta = yaml.safe_load((tmp_path / "intel.yaml").read_text())
    assert width_cells * meta["resolution"] < 42 and height_cells * meta["resolution"] < 42
