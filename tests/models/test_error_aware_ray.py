"""The error-aware model for laser rays: a scan of a known room, the neighbour rule, the ring."""

from __future__ import annotations

import math

import numpy as np

from gridmap_cli.mapping.grid import FrequencyAccumulator, GridSpec
from gridmap_cli.mapping.models.error_aware import ErrorAwareParams
from gridmap_cli.mapping.models.error_aware_ray import ErrorAwareRayModel, ScanLayout
from gridmap_cli.mapping.pipeline import batch_bounds
from gridmap_cli.poses.sync import SensorReadings
from gridmap_cli.robot import RangeSensor
from tests.models.test_error_aware import Linear

BEAMS = 181
LASER = tuple(
    RangeSensor(f"laser_{i}", 0.0, 0.0, math.radians(-90 + i), 0.0, 0.0, 8.0, "laser")
    for i in range(BEAMS)
)
SPEC = GridSpec(-2.5, -2.5, 0.05, 100, 100)  # a 4 m room, walls at +-2 m, with a margin


def room_scan(d_m: float = 0.0, phi_rad: float = 0.0) -> SensorReadings:
    """One scan from the centre of a 4 m square room, facing +x: ranges to its walls."""
    yaw = np.array([s.yaw_rad for s in LASER])
    z = 2.0 / np.maximum(np.abs(np.cos(yaw)), np.abs(np.sin(yaw)))
    n = BEAMS
    return SensorReadings(
        stamp_ns=np.zeros(n, dtype=np.int64),
        sensor=np.arange(n, dtype=np.int32),
        range_m=z,
        x_m=np.zeros(n),
        y_m=np.zeros(n),
        theta_rad=yaw,
        sensors=LASER,
        distance_m=np.full(n, d_m),
        rotation_rad=np.full(n, phi_rad),
    )


def model(odometry: Linear) -> ErrorAwareRayModel:
    layout = ScanLayout.of(LASER, np.ones(BEAMS, dtype=bool))
    return ErrorAwareRayModel(ErrorAwareParams(), odometry, layout, 0.05)


def test_layout_orders_the_beams_and_finds_the_step() -> None:
    layout = ScanLayout.of(LASER[::-1], np.ones(BEAMS, dtype=bool))
    assert layout.beams == BEAMS
    assert np.allclose(layout.step_rad, math.radians(1.0))
    assert list(layout.beam[:3]) == [180, 179, 178]  # ordered by yaw, not by position
    assert set(layout.scan) == {0}


def test_a_scan_with_a_known_pose_maps_the_room() -> None:
    grid = FrequencyAccumulator(SPEC)
    model(Linear()).accumulate(grid, room_scan())
    prob = grid.occupancy_map().prob
    cols, rows = np.meshgrid(np.arange(SPEC.width), np.arange(SPEC.height))
    x, y = SPEC.cell_center(cols, rows)
    wall_dist = np.abs(2.0 - np.maximum(np.abs(x), np.abs(y)))
    occupied = ~np.isnan(prob) & (prob >= 0.65)
    assert occupied.sum() > 100
    assert wall_dist[occupied].max() <= 0.075  # within a cell and a half of a wall
    # in front of the laser, inside the room and clear of the walls: free
    front = (x > 0.2) & (np.abs(y) < 1.5) & (x < 1.8)
    assert np.all(prob[front] <= 0.25)


def test_heading_error_keeps_free_claims_behind_the_nearest_neighbour() -> None:
    # a post 1 m ahead, seen by beam 90 only; its neighbours see the far wall at 2 m
    r = room_scan()
    z = r.range_m.copy()
    z[90] = 1.0
    scan = SensorReadings(**{**r.__dict__, "range_m": z})
    step = math.radians(1.0)
    for g, limited in ((0.0, []), (2.5 * step, [87, 88, 89, 91, 92, 93])):
        ev = model(Linear(c_g=g)).evidence(
            SensorReadings(**{**scan.__dict__, "distance_m": np.ones(BEAMS)})
        )
        near = [i for i in range(80, 101) if i != 90 and ev.free_m[i] < 1.0]
        assert near == limited


def test_a_near_echo_still_hits_a_cell_and_spreading_keeps_the_looks() -> None:
    r = room_scan()
    z = np.full(BEAMS, 8.0)  # no echo ...
    z[90] = 0.12  # ... but one beam 12 cm away: its ring is narrower than a cell
    scan = SensorReadings(**{**r.__dict__, "range_m": z})
    grid = FrequencyAccumulator(SPEC)
    model(Linear()).accumulate(grid, scan)
    assert grid.hits().max() > 0.5
    # widened by a heading error, the ring's looks spread over more cells, not more looks
    ev0 = model(Linear()).evidence(room_scan(1.0))
    ev1 = model(Linear(c_g=0.1)).evidence(room_scan(1.0))
    ratio = (ev1.ring_look * ev1.half_width_rad) / (ev0.ring_look * ev0.half_width_rad)
    assert np.allclose(ratio, 1.0)


def test_batches_are_cut_between_stamps() -> None:
    stamps = np.array([0, 0, 0, 1, 1, 1, 2, 2, 3], dtype=np.int64)
    assert batch_bounds(stamps, 4) == [(0, 6), (6, 9)]
    assert batch_bounds(stamps, 2) == [(0, 3), (3, 6), (6, 8), (8, 9)]
    assert batch_bounds(np.zeros(5, dtype=np.int64), 2) == [(0, 5)]
