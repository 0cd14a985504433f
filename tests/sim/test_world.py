"""Ray casting in :mod:`gridmap_cli.sim.world`."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gridmap_cli.mapping.grid import GridSpec
from gridmap_cli.sim.world import World

RES = 0.05


def half_plane_world(angle_deg: float, through: tuple[float, float] = (3.0, 2.5)) -> World:
    """A 6 m x 5 m world whose cells beyond a straight wall are occupied.

    The wall passes through ``through``; its outward normal (towards free space) points along
    ``angle_deg + 180``.
    """
    spec = GridSpec(0.0, 0.0, RES, 120, 100)
    rows, cols = np.mgrid[0 : spec.height, 0 : spec.width]
    x, y = spec.cell_center(cols, rows)
    a = math.radians(angle_deg)
    occ = (x - through[0]) * math.cos(a) + (y - through[1]) * math.sin(a) > 0.0
    return World(occ, spec)


def test_head_on_wall_distance_and_incidence() -> None:
    spec = GridSpec(0.0, 0.0, RES, 100, 60)
    occ = np.zeros(spec.shape, dtype=bool)
    occ[:, 80:] = True  # wall face at x = 4.0 m
    world = World(occ, spec)
    x = np.array([0.5, 1.0, 2.22, 3.9])
    rng, inc = world.cast(x, 1.5, 0.0, 5.0)
    np.testing.assert_allclose(rng, 4.0 - x, atol=1e-9)
    np.testing.assert_allclose(inc, 0.0, atol=math.radians(1.0))


@pytest.mark.parametrize("wall_deg", [0.0, 20.0, 45.0, 60.0, 75.0])
def test_oblique_wall_distance_within_a_cell(wall_deg: float) -> None:
    world = half_plane_world(wall_deg)
    a = math.radians(wall_deg)
    ox = np.array([1.0, 1.5, 2.0])
    oy = np.array([1.5, 2.5, 2.0])
    expected = (3.0 - ox) * math.cos(a) + (2.5 - oy) * math.sin(a)
    rng, inc = world.cast(ox, oy, a, 10.0)
    assert np.all(np.abs(rng - expected) <= RES * math.sqrt(2.0))
    np.testing.assert_allclose(inc, 0.0, atol=math.radians(3.0))


@pytest.mark.parametrize("wall_deg", [0.0, 30.0, 60.0, 90.0])
@pytest.mark.parametrize("side", [-1.0, 1.0])
def test_sixty_degree_incidence(wall_deg: float, side: float) -> None:
    world = half_plane_world(wall_deg)
    a = math.radians(wall_deg) + side * math.radians(60.0)
    rng, inc = world.cast(2.0, 2.0, a, 10.0)
    assert rng < 10.0
    assert math.degrees(float(inc)) == pytest.approx(60.0, abs=3.0)


def test_miss_reads_max_range_and_nan_incidence() -> None:
    spec = GridSpec(0.0, 0.0, RES, 40, 40)
    occ = np.zeros(spec.shape, dtype=bool)
    occ[35:, :] = True  # wall at the top only
    world = World(occ, spec)
    rng, inc = world.cast(1.0, 1.0, [-math.pi / 2, 0.0, math.pi / 2], [0.5, 3.0, 0.4])
    np.testing.assert_array_equal(rng[:2], [0.5, 3.0])
    assert np.isnan(inc[:2]).all()
    assert rng[2] == pytest.approx(0.4)  # the wall is 0.75 m away, beyond this ray's 0.4 m


def test_outside_the_grid_is_free_and_rays_may_enter() -> None:
    spec = GridSpec(10.0, 20.0, RES, 40, 40)  # 10..12 x 20..22
    occ = np.zeros(spec.shape, dtype=bool)
    occ[:, 20] = True  # one-cell wall at x in [11.0, 11.05)
    world = World(occ, spec)
    rng, inc = world.cast([9.0, 9.0, 11.5], [21.0, 23.0, 21.0], [0.0, 0.0, 0.0], 5.0)
    assert rng[0] == pytest.approx(2.0)  # starts outside, enters, hits the wall face
    assert inc[0] == pytest.approx(0.0, abs=0.05)
    assert rng[1] == 5.0  # passes above the grid: nothing to hit
    assert rng[2] == 5.0  # leaves the grid: no wall beyond it


def test_ray_starting_inside_an_obstacle_reads_zero() -> None:
    spec = GridSpec(0.0, 0.0, RES, 20, 20)
    occ = np.ones(spec.shape, dtype=bool)
    rng, inc = World(occ, spec).cast(0.5, 0.5, 1.0, 2.0)
    assert rng == 0.0
    assert 0.0 <= inc <= math.pi / 2


@pytest.mark.parametrize("angle", [-1e-110, 1e-110, 0.0, math.pi, math.pi - 1e-17, -math.pi / 2])
def test_ray_along_a_cell_boundary_next_to_a_wall(angle: float) -> None:
    """A ray lying on a row boundary, close to obstacles, must still walk cell by cell briskly."""
    spec = GridSpec(0.0, 0.0, 0.1, 200, 200)
    occ = np.zeros(spec.shape, dtype=bool)
    occ[:, :5] = True
    occ[:, 195:] = True
    occ[:5, :] = True
    occ[101, :] = True  # a wall just above the ray: the distance bound is no help
    occ[98, :] = True  # and one just below
    rng, _ = World(occ, spec).cast(10.0, 10.0, angle, 100.0)
    if abs(math.sin(angle)) > 0.5:
        assert float(rng) == pytest.approx(0.1, abs=1e-6)  # straight down onto row 98 (y < 9.9)
    else:
        assert float(rng) == pytest.approx(9.5, abs=1e-6)


def test_cast_keeps_the_broadcast_shape() -> None:
    world = half_plane_world(0.0)
    rng, inc = world.cast(np.full((3, 1, 1), 1.0), 2.0, np.zeros((1, 4, 5)), 10.0)
    assert rng.shape == inc.shape == (3, 4, 5)
    np.testing.assert_allclose(rng, 2.0)


def test_world_rejects_a_mismatched_grid() -> None:
    with pytest.raises(ValueError, match="shape"):
        World(np.zeros((3, 4), dtype=bool), GridSpec(0.0, 0.0, 1.0, 3, 4))


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(0.05, 2.9),
    y=st.floats(0.05, 4.95),
    angle_deg=st.floats(-85.0, 85.0),
)
def test_vertical_wall_exact_boundary(x: float, y: float, angle_deg: float) -> None:
    spec = GridSpec(0.0, 0.0, 0.1, 50, 50)
    occ = np.zeros(spec.shape, dtype=bool)
    occ[:, 30:] = True  # face at x = 3.0 m
    a = math.radians(angle_deg)
    expected = (3.0 - x) / math.cos(a)
    y_hit = y + expected * math.sin(a)
    rng, _ = World(occ, spec).cast(x, y, a, 100.0)
    if 1e-6 < y_hit < 5.0 - 1e-6:
        assert float(rng) == pytest.approx(expected, abs=1e-6)
    elif not (-1e-6 < y_hit < 5.0 + 1e-6):
        assert float(rng) == 100.0  # leaves through the top or bottom first


def reference_cast(
    occ: np.ndarray, spec: GridSpec, x: float, y: float, a: float, max_range: float
) -> float:
    """Textbook cell-by-cell traversal (Amanatides & Woo) of one ray starting inside the grid."""
    u = (x - spec.origin_x_m) / spec.resolution_m
    v = (y - spec.origin_y_m) / spec.resolution_m
    du, dv = math.cos(a), math.sin(a)
    col, row = math.floor(u), math.floor(v)
    t_max = max_range / spec.resolution_m
    t = 0.0
    while 0 <= col < spec.width and 0 <= row < spec.height and t < t_max:
        if occ[row, col]:
            return t * spec.resolution_m
        tu = ((col + 1 - u) / du if du > 0 else (col - u) / du) if du != 0 else math.inf
        tv = ((row + 1 - v) / dv if dv > 0 else (row - v) / dv) if dv != 0 else math.inf
        if tu < tv:
            t, col = tu, col + (1 if du > 0 else -1)
        else:
            t, row = tv, row + (1 if dv > 0 else -1)
    return max_range


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), density=st.floats(0.01, 0.3))
def test_cast_never_skips_a_cell(seed: int, density: float) -> None:
    """Against a cell-by-cell reference on random clutter: the same first cell, the same range."""
    gen = np.random.default_rng(seed)
    spec = GridSpec(-0.3, 0.2, 0.1, 30, 25)
    occ = gen.random(spec.shape) < density
    world = World(occ, spec)
    n = 30
    x = spec.origin_x_m + gen.uniform(0.0, 3.0, n)
    y = spec.origin_y_m + gen.uniform(0.0, 2.5, n)
    a = gen.uniform(-math.pi, math.pi, n)
    rng, _ = world.cast(x, y, a, 4.0)
    expected = [reference_cast(occ, spec, *ray, 4.0) for ray in zip(x, y, a, strict=True)]
    np.testing.assert_allclose(rng, expected, atol=1e-6)
