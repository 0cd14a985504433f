"""Raw odometry recovered from a corrected CARMEN log's ODOM increments, and the time line."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from gridmap_cli.geometry import compose, inverse
from gridmap_cli.readers.text.carmen_tracks import (
    STAMP_STEP_NS,
    Event,
    build_tracks,
    chain_increments,
    find_restarts,
    repair_stamps,
)


def test_chain_without_restarts_gives_back_the_logged_poses() -> None:
    poses = np.array([[1.0, 2.0, 0.3], [1.5, 2.2, 0.5], [2.0, 2.0, -0.4], [2.0, 1.0, 3.1]])
    out = chain_increments(poses, np.zeros(4, dtype=bool))
    np.testing.assert_allclose(out, poses, atol=1e-12)


def test_chain_ignores_the_jump_into_a_restart() -> None:
    # forward 1 m, restart jumps to (10, 10, pi/2), then forward 1 m in the restart's frame
    poses = np.array(
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [10.0, 10.0, math.pi / 2], [10.0, 11.0, math.pi / 2]]
    )
    out = chain_increments(poses, np.array([False, False, True, False]))
    np.testing.assert_allclose(out, [[0, 0, 0], [1, 0, 0], [1, 0, 0], [2, 0, 0]], atol=1e-12)


def _compose(
    a: tuple[float, float, float], b: tuple[float, float, float]
) -> tuple[float, float, float]:
    x, y, th = compose(np.float64(a[0]), np.float64(a[1]), np.float64(a[2]), b[0], b[1], b[2])
    return float(x), float(y), float(th)


@given(
    st.lists(
        st.tuples(st.floats(-0.5, 0.5), st.floats(-0.2, 0.2), st.floats(-0.6, 0.6), st.booleans()),
        min_size=2,
        max_size=40,
    ),
    st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(-3, 3)),
)
def test_restarts_at_any_pose_do_not_change_the_recovered_odometry(
    steps: list[tuple[float, float, float, bool]], anchor: tuple[float, float, float]
) -> None:
    """A corrected log re-anchors the logged odometry at arbitrary poses after scans; the chain
    of the increments is the raw odometry all the same."""
    raw = (0.0, 0.0, 0.0)
    frame = (0.0, 0.0, 0.0)  # logged = frame (+) raw
    logged, restart, expected = [raw], [False], [raw]
    for k, (dx, dy, dth, scan) in enumerate(steps, start=1):
        raw = _compose(raw, (dx, dy, dth))
        logged.append(_compose(frame, raw))
        restart.append(False)
        expected.append(raw)
        if scan:  # a scan at the corrected pose, then the restart line at it
            corrected = (anchor[0] + k, anchor[1] - k, anchor[2] + 0.1 * k)
            inv = inverse(np.float64(raw[0]), np.float64(raw[1]), np.float64(raw[2]))
            frame = _compose(corrected, (float(inv[0]), float(inv[1]), float(inv[2])))
            logged.append(corrected)
            restart.append(True)
            expected.append(raw)
    out = chain_increments(np.array(logged), np.array(restart))
    want = np.array(expected)
    np.testing.assert_allclose(out[:, :2], want[:, :2], atol=1e-6)
    np.testing.assert_allclose(np.cos(out[:, 2] - want[:, 2]), 1.0, atol=1e-9)


def test_restart_is_the_first_odom_after_a_scan_at_its_pose() -> None:
    events = [
        Event("odom", 1, 0, (0.0, 0.0, 0.0)),
        Event("odom", 2, 10, (1.0, 0.0, 0.0)),
        Event("scan", 3, 10, (1.1, 0.1, 0.0), 0),
        Event("odom", 4, 0, (1.1, 0.1, 0.0)),  # restart, moved: the log is corrected
        Event("odom", 5, 20, (1.1, 0.1, 0.0)),  # same pose again: a real (zero) increment
    ]
    restart, moved = find_restarts(events)
    assert restart == [False, False, False, True, False] and moved == 1


def test_raw_log_is_not_corrected_and_offers_no_truth() -> None:
    events = [
        Event("odom", 1, 0, (0.0, 0.0, 0.0)),
        Event("scan", 2, 5, (0.0, 0.0, 0.0), 0),
        Event("odom", 3, 10, (0.0, 0.0, 0.0)),  # standing still: equal, but nothing moved
        Event("odom", 4, 20, (1.0, 0.0, 0.0)),
    ]
    tracks = build_tracks("x.log", events, 4)
    assert tracks.truth is None and tracks.notes["carmen"].startswith("raw log")
    np.testing.assert_array_equal(tracks.odometry.stamp_ns, [0, 5, 20])


def test_repair_moves_backward_and_repeated_stamps_forward_only() -> None:
    out, backwards, repeats, largest = repair_stamps([0, 100_000, 100_000, 50_000, 200_000])
    assert out == [0, 100_000, 101_000, 102_000, 200_000]
    assert (backwards, repeats, largest) == (1, 1, 52_000)
    assert out[2] - out[1] == STAMP_STEP_NS


def test_constant_stamps_become_microseconds_in_file_order() -> None:
    out, _, repeats, _ = repair_stamps([7] * 5)
    assert out == [7 + i * STAMP_STEP_NS for i in range(5)] and repeats == 4


def test_the_odometry_stamps_the_repair_moved_are_kept_with_what_the_log_said() -> None:
    events = [
        Event("odom", 1, 0, (0.0, 0.0, 0.0)),
        Event("odom", 2, 2_000_000, (1.0, 0.0, 0.0)),
        Event("odom", 3, 1_000_000, (2.0, 0.0, 0.0)),  # went back: moved to 2 ms + 1 us
        Event("odom", 4, 3_000_000, (3.0, 0.0, 0.0)),
    ]
    tracks = build_tracks("x.log", events, 4)
    assert tracks.moved is not None
    np.testing.assert_array_equal(tracks.moved.stamp_ns, [2_000_000 + STAMP_STEP_NS])
    np.testing.assert_array_equal(tracks.moved.logged_ns, [1_000_000])
    in_order = [Event("odom", k + 1, k * 1_000_000, (float(k), 0.0, 0.0)) for k in range(3)]
    assert build_tracks("x.log", in_order, 3).moved is None
