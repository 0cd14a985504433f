"""The unit of CARMEN's fov/resolution PARAM lines is inferred from the beam count (issue 21)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from gridmap_cli.readers.text.carmen_layout import layout_from_params
from gridmap_cli.readers.text.carmen_log import read_carmen_log
from tests.readers.carmen_helpers import flaser, odom, write

HALF_DEG = math.pi / 360.0


@pytest.mark.parametrize(
    ("fov", "res", "read"),
    [
        (3.14159, None, "fov 3.14159 read as radians"),
        (180.0, None, "fov 180 deg"),
        (math.pi, 0.5, "resolution 0.5 deg"),
        (180.0, 0.00872665, "resolution 0.00872665 read as radians"),
        (None, 0.00872665, "resolution 0.00872665 read as radians"),
        (None, 0.5, "resolution 0.5 deg"),
    ],
)
def test_361_beams_span_180_degrees_whatever_the_unit(
    fov: float | None, res: float | None, read: str
) -> None:
    layout = layout_from_params(fov, res, 361, HALF_DEG)
    assert math.degrees(layout.start_rad) == pytest.approx(-90.0, abs=1e-3)
    assert math.degrees(layout.step_rad) == pytest.approx(0.5, abs=1e-5)
    assert read in layout.read


def test_no_params_keep_carmens_guess() -> None:
    layout = layout_from_params(None, None, 361, HALF_DEG)
    assert (layout.start_rad, layout.step_rad, layout.read) == (-math.pi / 2, HALF_DEG, "")


def test_a_fov_the_beams_do_not_span_is_said() -> None:
    layout = layout_from_params(90.0, 1.0, 361, HALF_DEG)
    assert math.degrees(layout.step_rad) == pytest.approx(1.0)  # the resolution wins
    assert "do not span the fov 90 deg" in layout.read


def test_radian_fov_in_a_log_turns_no_beam_and_inspect_says_what_was_read(
    tmp_path: Path,
) -> None:
    header = "PARAM laser_front_laser_fov 3.14159 nohost 0\n"
    lines = [odom((0, 0, 0), 1.0), flaser([1.0] * 361, (0, 0, 0), 1.0)]
    log = read_carmen_log(write(tmp_path, lines, header=header))
    assert log.sensors is not None
    assert math.degrees(log.sensors[0].yaw_rad) == pytest.approx(-90.0, abs=1e-3)
    assert math.degrees(log.sensors[-1].yaw_rad) == pytest.approx(90.0, abs=1e-3)
    assert "PARAM fov 3.14159 read as radians (180 deg" in log.metadata["frontlaser"]
