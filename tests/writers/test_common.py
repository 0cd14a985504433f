"""What every writer shares (gridmap_cli/writers/__init__.py)."""

from __future__ import annotations

import errno
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.errors import GridmapError, OutputExistsError, UsageError, naming
from gridmap_cli.mapping.grid import GridSpec, OccupancyMap
from gridmap_cli.records import PoseTrack, RangeLog, RangeReadings
from gridmap_cli.robot import RangeSensor
from gridmap_cli.writers import aria_log, check_output, map_mcap, mcap_log
from tests.helpers import names


def test_check_output_refuses_a_directory_even_with_force(tmp_path: Path) -> None:
    for force in (False, True):
        with pytest.raises(UsageError, match=rf"^{tmp_path} is a directory$"):
            check_output(tmp_path, force)


def test_check_output_refuses_an_existing_file_without_force(tmp_path: Path) -> None:
    target = tmp_path / "out.csv"
    check_output(target, force=False)  # nothing there yet
    target.write_text("old")
    with pytest.raises(OutputExistsError, match=r"out\.csv exists \(use force=True to overwrite"):
        check_output(target, force=False)
    with naming("flags"), pytest.raises(OutputExistsError, match=r"\(use --force to overwrite\)"):
        check_output(target, force=False)
    check_output(target, force=True)
    assert target.read_text() == "old"


def _disk_full(*args: object, **kwargs: object) -> None:
    raise OSError(errno.ENOSPC, "No space left on device")


@pytest.mark.parametrize("saver", ["aria", "mcap", "map"])
def test_a_failed_write_is_one_error_line_and_leaves_the_old_file(
    saver: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every saver goes through atomic.atomic_write (CSV: tests/writers/test_csv_log.py)."""
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    sensors = (RangeSensor("sonar0", 0.0, 0.0, 0.0, 0.4, 0.1, 4.0),)
    log = RangeLog(
        "mem",
        PoseTrack(np.zeros(1, np.int64), np.zeros(1), np.zeros(1), np.zeros(1)),
        RangeReadings(np.zeros(1, np.int64), np.zeros(1, np.int32), np.ones(1)),
        ("sonar0",),
    )
    with pytest.raises(GridmapError) as info:
        if saver == "aria":
            monkeypatch.setattr(aria_log, "write_aria_log", _disk_full)
            aria_log.save_aria_log(log, sensors, target)
        elif saver == "mcap":
            monkeypatch.setattr(mcap_log, "write_mcap_log", _disk_full)
            mcap_log.save_mcap_log(log, sensors, target)
        else:
            monkeypatch.setattr(map_mcap, "mcap_writer", _disk_full)
            omap = OccupancyMap(GridSpec(0.0, 0.0, 1.0, 1, 1), np.array([[0.5]]))
            map_mcap.write_map_mcap(target, omap, force=True)
    what = "the map" if saver == "map" else "the log"
    assert str(info.value) == f"{target}: cannot write {what}: No space left on device"
    assert target.read_bytes() == b"old"
    assert names(tmp_path) == {"out.bin"}
