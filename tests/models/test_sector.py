"""The span kernel must select exactly the cells whose centres lie inside each beam sector."""

from __future__ import annotations

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.mapping.grid import GridSpec
from gridmap_cli.mapping.models.sector import sector_bounds, sector_rows

SPEC = GridSpec(origin_x_m=-3.0, origin_y_m=-2.0, resolution_m=0.1, width=60, height=45)


def brute_force(spec: GridSpec, x: float, y: float, th: float, h: float, r: float) -> set:
    cols, rows = np.meshgrid(np.arange(spec.width), np.arange(spec.height))
    cx, cy = spec.cell_center(cols, rows)
    dx, dy = cx - x, cy - y
    dist = np.hypot(dx, dy)
    bearing = wrap_angle(np.arctan2(dy, dx) - th)
    inside = (dist <= r) & (np.abs(bearing) <= h)
    return {(int(j), int(i)) for j, i in zip(rows[inside], cols[inside], strict=True)}


def kernel(spec: GridSpec, x: float, y: float, th: float, h: float, r: float) -> set:
    a = lambda v: np.asarray([v], dtype=np.float64)  # noqa: E731
    rows = sector_rows(spec, a(x), a(y), a(th), a(h), a(r))
    spans = rows.spans(a(r))
    out = set()
    for j, c0, c1 in zip(spans.row, spans.col0, spans.col1, strict=True):
        for i in range(c0, c1 + 1):
            assert (int(j), i) not in out, "a cell was covered twice by one sector"
            out.add((int(j), i))
    return out


@settings(max_examples=300, deadline=None)
@example(x=0.75, y=0.65, th=0.0, h=1.0, r=1.0)  # apex on a cell centre, a 3-4-5 cell on the arc
@given(
    x=st.floats(-4.0, 4.0),
    y=st.floats(-3.0, 3.5),
    th=st.floats(-np.pi, np.pi),
    h=st.floats(0.01, 1.5),
    r=st.floats(0.0, 4.0),
)
def test_spans_equal_brute_force(x: float, y: float, th: float, h: float, r: float) -> None:
    got = kernel(SPEC, x, y, th, h, r)
    want = brute_force(SPEC, x, y, th, h, r)
    # cell centres lying on the boundary within float noise may go either way
    diff = got ^ want
    if diff:
        cols = np.array([c for _, c in diff])
        rows = np.array([j for j, _ in diff])
        cx, cy = SPEC.cell_center(cols, rows)
        dist = np.hypot(cx - x, cy - y)
        bearing = np.abs(wrap_angle(np.arctan2(cy - y, cx - x) - th))
        # the apex itself (distance 0) lies on both wedge edges
        on_edge = (np.abs(dist - r) < 1e-9) | (np.abs(bearing - h) < 1e-9) | (dist < 1e-9)
        assert on_edge.all(), f"{len(diff)} cells differ, e.g. {sorted(diff)[:5]}"


def test_axis_aligned_beam_has_expected_cells() -> None:
    # a beam pointing straight up the y axis, 90 degrees wide, reach 0.35 m on a 0.1 m grid
    spec = GridSpec(0.0, 0.0, 0.1, 10, 10)
    cells = kernel(spec, 0.5, 0.5, np.pi / 2, np.pi / 4, 0.35)
    # centres at (0.55, 0.55..0.75) and diagonals within 45 degrees and 0.35 m
    assert (5, 5) in cells and (6, 5) in cells and (7, 5) in cells
    assert (8, 5) not in cells  # 0.35 m reach ends before the centre at 0.85 m
    assert (4, 5) not in cells  # behind the sensor
    assert all(j >= 5 for j, _ in cells)


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(-10, 10),
    y=st.floats(-10, 10),
    th=st.floats(-np.pi, np.pi),
    h=st.floats(0.01, 1.5),
    r=st.floats(0.01, 5.0),
)
def test_bounds_contain_the_whole_sector(x: float, y: float, th: float, h: float, r: float) -> None:
    xmin, ymin, xmax, ymax = sector_bounds(
        np.array([x]), np.array([y]), np.array([th]), np.array([h]), np.array([r])
    )
    angles = th + np.linspace(-h, h, 401)
    px = np.concatenate([[x], x + r * np.cos(angles)])
    py = np.concatenate([[y], y + r * np.sin(angles)])
    eps = 1e-9
    assert px.min() >= xmin - eps and px.max() <= xmax + eps
    assert py.min() >= ymin - eps and py.max() <= ymax + eps
