"""rosbag2 ``metadata.yaml`` checked against its files (``readers/ros/bag/metadata.py``):
compressed folders as rosbag2 writes them read as the plain one; metadata that contradicts the
files is one line naming the file (the corpus holds the variations)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.errors import InputFileError
from gridmap_cli.readers import read_log
from tests.helpers import run
from tests.readers.bag_helpers import write_rosbag2
from tests.readers.mcap_helpers import one_sonar_log


@pytest.fixture
def recording(tmp_path: Path) -> Path:
    return one_sonar_log(tmp_path / "ros2.mcap")


@pytest.mark.parametrize("compression", ["file", "message"])
def test_a_zstd_compressed_folder_reads_as_the_plain_one(
    recording: Path, tmp_path: Path, compression: str
) -> None:
    plain = read_log(write_rosbag2(recording, tmp_path / "plain"))
    packed = read_log(write_rosbag2(recording, tmp_path / "z", compression=compression))
    assert np.array_equal(packed.readings.range_m, plain.readings.range_m)
    assert np.array_equal(packed.poses.stamp_ns, plain.poses.stamp_ns)
    assert len(plain.readings.range_m) > 0


def test_messages_compressed_behind_plain_metadata_say_so(recording: Path, tmp_path: Path) -> None:
    bag = write_rosbag2(recording, tmp_path / "z", compression="message")
    meta = bag / "metadata.yaml"
    meta.write_text(meta.read_text().replace("compression_mode: message", "compression_mode: ''"))
    with pytest.raises(InputFileError, match=r"message 1 of .*it is zstd-compressed"):
        read_log(bag)
    code, _, err = run("build", str(bag), "-o", str(tmp_path / "m.png"))
    assert code == 1 and err.count("\n") == 1 and "zstd-compressed" in err, err
    assert not (tmp_path / "m.png").exists()
