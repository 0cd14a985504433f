"""Path files and true trajectories (:mod:`gridmap_cli.sim.path`)."""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.errors import InputFileError
from gridmap_cli.geometry import wrap_angle
from gridmap_cli.sim.path import WaypointPath, load_path, parse_path_yaml, trajectory


def path_of(*waypoints: tuple[float, float], **kwargs: object) -> WaypointPath:
    return WaypointPath(waypoints=np.asarray(waypoints, dtype=np.float64), **kwargs)  # type: ignore[arg-type]


def test_parse_full_file() -> None:
    text = """\
gridmap-path: 1
waypoints:
  - [0, 0]
  - [4.5, 0]
  - [4.5, 2]
speed_m_s: 0.5
turn_rate_deg_s: 30
laps: 3
start_heading_deg: 90
"""
    path = parse_path_yaml(text, "p.yaml")
    np.testing.assert_array_equal(path.waypoints, [[0, 0], [4.5, 0], [4.5, 2]])
    assert path.speed_m_s == 0.5
    assert path.turn_rate_rad_s == pytest.approx(math.radians(30))
    assert path.laps == 3
    assert path.closed  # laps > 1 close the path
    assert path.start_heading_rad == pytest.approx(math.pi / 2)
    assert path.source == "p.yaml"


def test_parse_defaults_and_closing_waypoint() -> None:
    path = parse_path_yaml("gridmap-path: 1\nwaypoints: [[0, 0], [1, 0], [1, 1], [0, 0]]\n", "p")
    assert path.speed_m_s == 0.4
    assert path.turn_rate_rad_s == pytest.approx(math.radians(40))
    assert path.laps == 1
    assert path.start_heading_rad is None
    # a last waypoint equal to the first closes the path
    assert path.closed
    assert path.waypoints.shape == (3, 2)


def test_load_path_from_file_and_handle(tmp_path: Path) -> None:
    text = "gridmap-path: 1\nwaypoints: [[0, 0], [1, 0]]\nclosed: true\n"
    f = tmp_path / "p.yaml"
    f.write_text(text)
    assert load_path(f).closed
    assert load_path(str(f)).source == str(f)
    assert load_path(io.StringIO(text)).closed


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("gridmap-path: 1\nwaypoints:\n  - [0, 0]\n  - [1, x]\n", 4, "waypoint 2 must be [x, y]"),
        ("gridmap-path: 1\nwaypoints:\n  - [0, 0]\n  - [1, 0, 2]\n", 4, "waypoint 2"),
        ("gridmap-path: 1\nwaypoints:\n  - [0, 0]\n  - [1, 0]\n  - [1, 0]\n", 5, "repeats"),
        ("gridmap-path: 1\nwaypoints: [[0, 0]]\n", 2, "at least two"),
        ("gridmap-path: 1\nwaypoints: [[0, 0], [1, 0]]\nspeed: 3\n", 3, "unknown key 'speed'"),
        ("gridmap-path: 1\nwaypoints: [[0, 0], [1, 0]]\nspeed_m_s: -1\n", 3, "must be > 0"),
        ("gridmap-path: 1\nwaypoints: [[0, 0], [1, 0]]\nturn_rate_deg_s: x\n", 3, "finite"),
        ("gridmap-path: 1\nwaypoints: [[0, 0], [1, 0]]\nlaps: 1.5\n", 3, "'laps'"),
        ("gridmap-path: 1\nwaypoints: [[0, 0], [1, 0]]\nclosed: 1\n", 3, "'closed'"),
        (
            "gridmap-path: 1\nwaypoints: [[0, 0], [1, 0]]\nlaps: 2\nclosed: false\n",
            4,
            "contradicts",
        ),
        ("gridmap-path: 2\nwaypoints: [[0, 0], [1, 0]]\n", 1, "gridmap-path: 1"),
        ("gridmap-path: 1\nwaypoints: [[0, 0], [1, 0]\n", 3, "not valid YAML"),
    ],
)
def test_parse_errors_name_the_line(text: str, line: int, message: str) -> None:
    with pytest.raises(InputFileError) as info:
        parse_path_yaml(text, "route.yaml")
    assert info.value.line == line
    assert message in info.value.detail
    assert str(info.value).startswith(f"route.yaml:{line}: ")


def test_parse_error_without_a_line() -> None:
    with pytest.raises(InputFileError, match=r"^route.yaml: expected a mapping"):
        parse_path_yaml("- 1\n- 2\n", "route.yaml")


def test_missing_file_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="cannot read"):
        load_path(tmp_path / "absent.yaml")


def test_straight_line_timing_and_poses() -> None:
    track = trajectory(path_of((1.0, 2.0), (5.0, 2.0)), rate_hz=10.0)
    assert len(track) == 101  # 4 m at 0.4 m/s: 10 s, both ends sampled
    np.testing.assert_array_equal(track.stamp_ns, np.arange(101) * 100_000_000)
    np.testing.assert_allclose(track.x_m, 1.0 + 0.04 * np.arange(101), atol=1e-12)
    np.testing.assert_allclose(track.y_m, 2.0)
    np.testing.assert_allclose(track.theta_rad, 0.0)


def test_turns_in_place_at_waypoints() -> None:
    # 1 m (2.5 s), a 90 deg left turn at 40 deg/s (2.25 s), 1 m (2.5 s)
    track = trajectory(path_of((0.0, 0.0), (1.0, 0.0), (1.0, 1.0)), rate_hz=100.0)
    t = track.stamp_ns / 1e9
    assert t[-1] == pytest.approx(7.25)
    turning = (t > 2.5 + 1e-9) & (t < 4.75 - 1e-9)
    np.testing.assert_allclose(track.x_m[turning], 1.0, atol=1e-12)
    np.testing.assert_allclose(track.y_m[turning], 0.0, atol=1e-12)
    np.testing.assert_allclose(track.theta_rad[turning], np.radians(40.0) * (t[turning] - 2.5))
    assert track.theta_rad[-1] == pytest.approx(math.pi / 2)
    assert (track.x_m[-1], track.y_m[-1]) == pytest.approx((1.0, 1.0))


def test_turns_the_shorter_way_and_honours_the_start_heading() -> None:
    path = path_of((0.0, 0.0), (0.0, -1.0), start_heading_rad=math.radians(170.0))
    track = trajectory(path, rate_hz=50.0)
    # from 170 deg to -90 deg: 100 deg to the left through 180, not 260 to the right
    assert track.theta_rad[0] == pytest.approx(math.radians(170.0))
    turn = np.diff(np.unwrap(track.theta_rad))
    assert (turn >= -1e-12).all()
    assert np.unwrap(track.theta_rad)[-1] == pytest.approx(math.radians(270.0))
    assert track.stamp_ns[-1] / 1e9 == pytest.approx(100.0 / 40.0 + 1.0 / 0.4)


def test_closed_laps_return_to_the_start() -> None:
    square = ((0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0))
    one = trajectory(path_of(*square, closed=True), rate_hz=20.0)
    three = trajectory(path_of(*square, laps=3, closed=True), rate_hz=20.0)
    for track in (one, three):
        assert (track.x_m[-1], track.y_m[-1]) == pytest.approx((0.0, 0.0), abs=1e-9)
    # lap one: 8 m and three 90 deg turns; later laps add the turn at the start
    lap1 = 8.0 / 0.4 + 3 * 2.25
    assert one.stamp_ns[-1] / 1e9 == pytest.approx(lap1)
    assert three.stamp_ns[-1] / 1e9 == pytest.approx(lap1 + 2 * (lap1 + 2.25))


def test_duration_repeats_laps_periodically() -> None:
    path = path_of((0.0, 0.0), (2.0, 0.0), (2.0, 1.0))  # open: closed for lapping
    track = trajectory(path, rate_hz=10.0, duration_s=3600.0)
    assert len(track) == 36_000
    assert track.stamp_ns[-1] == 3_599_900_000_000
    assert (np.diff(track.stamp_ns) > 0).all()
    # every pose lies on the closed triangle
    x, y = track.x_m, track.y_m
    on_edge = (np.abs(y) < 1e-9) | (np.abs(x - 2.0) < 1e-9) | (np.abs(y - 0.5 * x) < 1e-9)
    assert on_edge.all()
    # The robot is back at the start once per lap. Lap one has no turn at the start (it starts
    # facing waypoint 2); later laps begin with the 153.4 deg turn from the closing leg.
    turns_deg = (
        90.0
        + (90.0 + math.degrees(math.atan2(1.0, 2.0)))
        + (180.0 - math.degrees(math.atan2(1.0, 2.0)))
    )
    drive_s = (3.0 + math.sqrt(5.0)) / 0.4
    first_s = drive_s + (90.0 + 90.0 + math.degrees(math.atan2(1.0, 2.0))) / 40.0
    lap_s = drive_s + turns_deg / 40.0
    arrivals = math.floor((3599.9 - first_s) / lap_s) + 1
    at_start = np.hypot(x, y) < 1e-9
    visits = int(at_start[0]) + int(np.count_nonzero(at_start[1:] & ~at_start[:-1]))
    assert visits == 1 + arrivals


def test_duration_shorter_than_a_lap_truncates() -> None:
    track = trajectory(path_of((0.0, 0.0), (10.0, 0.0)), rate_hz=5.0, duration_s=2.0)
    assert len(track) == 10
    assert track.x_m[-1] == pytest.approx(0.4 * 1.8)


def test_theta_is_wrapped() -> None:
    track = trajectory(path_of((0.0, 0.0), (-1.0, 0.0), (-1.0, -1.0), laps=2, closed=True), 10.0)
    np.testing.assert_array_equal(track.theta_rad, wrap_angle(track.theta_rad))


@pytest.mark.parametrize(("rate", "duration"), [(0.0, None), (-1.0, None), (10.0, 0.0)])
def test_trajectory_rejects_bad_rates(rate: float, duration: float | None) -> None:
    with pytest.raises(ValueError):
        trajectory(path_of((0.0, 0.0), (1.0, 0.0)), rate, duration)
