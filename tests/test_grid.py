"""Grid geometry: world <-> cell round trips and the grid that covers a box (hypothesis)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gridmap_cli.errors import MapSizeError
from gridmap_cli.mapping.grid import GridSpec

# Map-sized values: coordinates within 100 km, cells from 1 mm to 10 m.
coords = st.floats(min_value=-1e5, max_value=1e5, allow_nan=False)
resolutions = st.floats(min_value=1e-3, max_value=10.0)
cells = st.integers(min_value=-100_000, max_value=100_000)


@st.composite
def specs(draw: st.DrawFn) -> GridSpec:
    return GridSpec(draw(coords), draw(coords), draw(resolutions), 100, 100)


@given(specs(), cells, cells)
def test_cell_center_maps_back_to_the_same_cell(spec: GridSpec, col: int, row: int) -> None:
    x, y = spec.cell_center(np.array([col]), np.array([row]))
    back_col, back_row = spec.world_to_cell(x, y)
    assert (int(back_col[0]), int(back_row[0])) == (col, row)


@given(specs(), coords, coords)
def test_a_point_lies_within_half_a_cell_of_its_cells_centre(
    spec: GridSpec, x: float, y: float
) -> None:
    col, row = spec.world_to_cell(np.array([x]), np.array([y]))
    cx, cy = spec.cell_center(col, row)
    # half a cell, plus rounding of coordinates up to 1e5 m
    slack = 0.5 * spec.resolution_m + 1e-9 * (1.0 + abs(x) + abs(y) + abs(spec.origin_x_m))
    assert abs(float(cx[0]) - x) <= slack
    assert abs(float(cy[0]) - y) <= slack + 1e-9 * abs(spec.origin_y_m)


@given(specs())
def test_cell_zero_zero_has_the_origin_at_its_lower_left_corner(spec: GridSpec) -> None:
    cx, cy = spec.cell_center(np.array([0]), np.array([0]))
    assert math.isclose(float(cx[0]) - 0.5 * spec.resolution_m, spec.origin_x_m, abs_tol=1e-6)
    assert math.isclose(float(cy[0]) - 0.5 * spec.resolution_m, spec.origin_y_m, abs_tol=1e-6)


@st.composite
def boxes(draw: st.DrawFn) -> tuple[float, float, float, float]:
    x0, x1 = sorted((draw(coords), draw(coords)))
    y0, y1 = sorted((draw(coords), draw(coords)))
    return x0, y0, x1, y1


@given(boxes(), resolutions, st.floats(min_value=0.0, max_value=10.0))
def test_covering_covers_the_box_plus_margin(
    box: tuple[float, float, float, float], res: float, margin: float
) -> None:
    xmin, ymin, xmax, ymax = box
    spec = GridSpec.covering(xmin, ymin, xmax, ymax, res, margin, max_cells=10**18)
    tol = 1e-9 * (1.0 + max(abs(v) for v in box) + margin)
    assert spec.resolution_m == res
    assert spec.width >= 1 and spec.height >= 1
    assert spec.origin_x_m <= xmin - margin + tol
    assert spec.origin_y_m <= ymin - margin + tol
    assert spec.origin_x_m + spec.width * res >= xmax + margin - tol
    assert spec.origin_y_m + spec.height * res >= ymax + margin - tol
    # and not much larger: at most one cell of slack on each side
    assert spec.width * res <= (xmax - xmin) + 2 * margin + 2 * res + tol
    assert spec.height * res <= (ymax - ymin) + 2 * margin + 2 * res + tol
    # the origin is aligned to the resolution, so maps of overlapping logs share cell edges
    k = spec.origin_x_m / res
    assert abs(k - round(k)) <= 1e-6 * (1.0 + abs(k))


@given(boxes(), resolutions)
def test_covering_puts_every_point_of_the_box_in_a_cell_of_the_grid(
    box: tuple[float, float, float, float], res: float
) -> None:
    xmin, ymin, xmax, ymax = box
    spec = GridSpec.covering(xmin, ymin, xmax, ymax, res, margin_m=res, max_cells=10**18)
    xs = np.array([xmin, xmax, 0.5 * (xmin + xmax)])
    ys = np.array([ymin, ymax, 0.5 * (ymin + ymax)])
    col, row = spec.world_to_cell(xs, ys)
    assert np.all((col >= 0) & (col < spec.width))
    assert np.all((row >= 0) & (row < spec.height))


@given(
    st.floats(min_value=1e5, max_value=1e12),
    st.floats(min_value=1e-3, max_value=0.1),
)
def test_covering_refuses_absurd_boxes(span: float, res: float) -> None:
    # at least 1e6 x 1e6 cells: 1e12, far above the default limit of 1e8
    with pytest.raises(MapSizeError, match="more than 100000000 cells"):
        GridSpec.covering(-span / 2, -span / 2, span / 2, span / 2, res)


@pytest.mark.parametrize(
    "box",
    [
        (math.nan, 0.0, 1.0, 1.0),
        (0.0, 0.0, math.inf, 1.0),
        (1.0, 0.0, 0.0, 1.0),  # xmin > xmax: no data at all
    ],
)
def test_covering_refuses_boxes_without_finite_extent(box: tuple[float, ...]) -> None:
    with pytest.raises(MapSizeError, match="no finite extent"):
        GridSpec.covering(*box, 0.05)


@pytest.mark.parametrize("res", [0.0, -0.05, math.nan, math.inf])
def test_covering_refuses_bad_resolutions(res: float) -> None:
    with pytest.raises(MapSizeError, match="resolution"):
        GridSpec.covering(0.0, 0.0, 1.0, 1.0, res)


def test_covering_a_single_point_gives_one_cell() -> None:
    spec = GridSpec.covering(2.0, 3.0, 2.0, 3.0, 0.5)
    assert (spec.width, spec.height) == (1, 1)
    col, row = spec.world_to_cell(np.array([2.0]), np.array([3.0]))
    assert (int(col[0]), int(row[0])) == (0, 0)
