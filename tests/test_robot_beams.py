"""The beam sensors of a laser whose scans change their geometry (gridmap_cli/robot/beams.py)."""

from __future__ import annotations

import math

import numpy as np

from gridmap_cli.robot import BeamBook

STEP = math.radians(1.0)


def directions(book: BeamBook) -> np.ndarray:
    return book.start + book.local * book.step


def test_the_first_scan_is_beams_in_order_and_its_geometry_again_adds_none() -> None:
    book = BeamBook(-math.pi / 2, STEP, 181)
    assert book.sensors(-math.pi / 2, STEP, 181).tolist() == list(range(181))
    assert book.sensors(-math.pi / 2, STEP, 180).tolist() == list(range(180))  # a beam short
    assert len(book) == 181 and book.varied


def test_interleaved_start_angles_are_new_directions_in_beam_order() -> None:
    book = BeamBook(-math.pi / 2, STEP, 181)
    for turn in (1, 2, 3):
        sensors = book.sensors(-math.pi / 2 + turn * STEP / 4, STEP, 180)
        assert sensors.tolist() == list(range(181 + 180 * (turn - 1), 181 + 180 * turn))
    expected = -math.pi / 2 + np.arange(721) * STEP / 4
    np.testing.assert_allclose(np.sort(directions(book)), expected, atol=1e-12)


def test_a_scan_starting_a_beam_later_reuses_the_directions_it_shares() -> None:
    book = BeamBook(-1.5708, 0.017453, 181)  # decimal angles, as drivers print them
    later = book.sensors(-1.5708 + 0.017453, 0.017453, 181)
    assert later[:180].tolist() == list(range(1, 181)) and later[180] == 181
    assert len(book) == 182
    assert directions(book)[181] == -1.5708 + 0.017453 + 180 * 0.017453


def test_a_jittering_start_angle_stays_within_the_bins() -> None:
    """A driver that moves its start angle a little at every scan makes no more sensors than
    there are bins of directions across its span."""
    book = BeamBook(-math.pi / 2, STEP, 181)
    rng = np.random.default_rng(1)
    for jitter in rng.uniform(-2e-4, 2e-4, 500):
        sensors = book.sensors(-math.pi / 2 + float(jitter), STEP, 181)
        assert len(set(sensors.tolist())) == 181  # one scan never shares a sensor
    assert len(book) <= 181 * 6
