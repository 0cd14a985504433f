"""The ray model: exact grid traversal, evidence along one ray, and a whole laser scan mapped."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from gridmap_cli.mapping.grid import GridSpec, LogOddsAccumulator, logodds
from gridmap_cli.mapping.models.ray import RayModel, RayParams, RaySegments, row_runs
from gridmap_cli.mapping.pipeline import BuildOptions, build_map
from gridmap_cli.poses.sync import SensorReadings
from gridmap_cli.records import PoseTrack, RangeLog, RangeReadings
from gridmap_cli.robot import RangeSensor

SPEC = GridSpec(origin_x_m=-2.0, origin_y_m=-1.5, resolution_m=0.1, width=40, height=30)
LASER = RangeSensor("laser", 0.0, 0.0, 0.0, 0.0, 0.02, 8.0, kind="laser")

Cell = tuple[int, int]  # (row, col)


# --- traversal against brute force -------------------------------------------------------------


def traversed(spec: GridSpec, x0: float, y0: float, x1: float, y1: float) -> set[Cell]:
    a = lambda v: np.array([v], dtype=np.float64)  # noqa: E731
    runs = row_runs(spec, RaySegments(a(x0), a(y0), a(x1), a(y1), np.array([True])))
    out: set[Cell] = set()
    for r, c0, c1 in zip(runs.row, runs.col0, runs.col1, strict=True):
        for c in range(int(c0), int(c1) + 1):
            assert (int(r), c) not in out, "a cell was visited twice by one ray"
            out.add((int(r), c))
    return out


def sampled(spec: GridSpec, x0: float, y0: float, x1: float, y1: float) -> set[Cell]:
    """Cells of points sampled along the segment every 1/1000 cell.

    Two consecutive samples in diagonal cells mean the segment passed near a cell corner and
    may have clipped a third cell between them; such intervals are bisected down to 1e-11 m.
    """
    res = spec.resolution_m
    length_m = math.hypot(x1 - x0, y1 - y0)

    def cell(t: float) -> Cell:
        u = (x0 + t * (x1 - x0) - spec.origin_x_m) / res
        v = (y0 + t * (y1 - y0) - spec.origin_y_m) / res
        return math.floor(v), math.floor(u)

    def diagonal(a: Cell, b: Cell) -> bool:
        return a[0] != b[0] and a[1] != b[1]

    out: set[Cell] = set()

    def refine(ta: float, tb: float, ca: Cell, cb: Cell) -> None:
        if (tb - ta) * length_m < 1e-11:
            return
        tm = 0.5 * (ta + tb)
        cm = cell(tm)
        out.add(cm)
        if diagonal(ca, cm):
            refine(ta, tm, ca, cm)
        if diagonal(cm, cb):
            refine(tm, tb, cm, cb)

    ts = np.linspace(0.0, 1.0, max(2, int(length_m / res * 1000) + 2))
    # the end point exactly, not x0 + 1 * (x1 - x0), which may round across a boundary
    xs = np.where(ts < 1.0, x0 + ts * (x1 - x0), x1)
    ys = np.where(ts < 1.0, y0 + ts * (y1 - y0), y1)
    cols = np.floor((xs - spec.origin_x_m) / res).astype(int)
    rows = np.floor((ys - spec.origin_y_m) / res).astype(int)
    out.update(zip(rows.tolist(), cols.tolist(), strict=True))
    for i in np.flatnonzero((np.diff(rows) != 0) & (np.diff(cols) != 0)):
        refine(float(ts[i]), float(ts[i + 1]), (rows[i], cols[i]), (rows[i + 1], cols[i + 1]))
    return {(r, c) for r, c in out if 0 <= r < spec.height and 0 <= c < spec.width}


def corner_distance_m(spec: GridSpec, cell: Cell, x0: float, y0: float, x1: float, y1: float):
    """Distance from the segment to the nearest of the cell's four corners, metres."""
    r, c = cell
    p0 = np.array([x0, y0])
    d = np.array([x1 - x0, y1 - y0])
    best = math.inf
    for dr in (0, 1):
        for dc in (0, 1):
            q = np.array([spec.origin_x_m + (c + dc) * spec.resolution_m,
                          spec.origin_y_m + (r + dr) * spec.resolution_m])  # fmt: skip
            dd = float(d @ d)
            t = 0.0 if dd == 0.0 else min(1.0, max(0.0, float((q - p0) @ d) / dd))
            best = min(best, float(np.linalg.norm(p0 + t * d - q)))
    return best


@settings(max_examples=300, deadline=None)
@example(x0=0.05, y0=0.05, x1=1.05, y1=1.05)  # 45 degrees through cell corners
@example(x0=-3.0, y0=0.0, x1=3.0, y1=0.0)  # along a grid line, across the whole grid
@example(x0=0.25, y0=0.3, x1=1.75, y1=0.3000000000001)  # nearly flat, crossing a row boundary
@example(x0=0.5, y0=-2.5, x1=0.5, y1=2.5)  # vertical on a column boundary, through the grid
@example(x0=0.33, y0=0.77, x1=0.33, y1=0.77)  # length 0
@example(x0=-2.9, y0=-2.4, x1=-2.1, y1=-1.6)  # entirely outside
@given(
    x0=st.floats(-3.0, 3.0),
    y0=st.floats(-2.5, 2.5),
    x1=st.floats(-3.0, 3.0),
    y1=st.floats(-2.5, 2.5),
)
def test_traversal_visits_exactly_the_cells_the_segment_meets(
    x0: float, y0: float, x1: float, y1: float
) -> None:
    got = traversed(SPEC, x0, y0, x1, y1)
    want = sampled(SPEC, x0, y0, x1, y1)
    for cell in got ^ want:
        # at a corner the two cells beside it may go either way (Amanatides and Woo take one)
        assert corner_distance_m(SPEC, cell, x0, y0, x1, y1) < 1e-9, (
            f"cell {cell} {'only traversed' if cell in got else 'missed'}"
        )


def test_runs_stay_inside_the_grid_for_rays_far_outside() -> None:
    rng = np.random.default_rng(3)
    n = 2000
    seg = RaySegments(
        rng.uniform(-50, 50, n),
        rng.uniform(-50, 50, n),
        rng.uniform(-50, 50, n),
        rng.uniform(-50, 50, n),
        rng.random(n) < 0.5,
    )
    runs = row_runs(SPEC, seg)
    assert np.all((runs.row >= 0) & (runs.row < SPEC.height))
    assert np.all((runs.col0 >= 0) & (runs.col0 <= runs.col1) & (runs.col1 < SPEC.width))


# --- one ray -------------------------------------------------------------------------------------


def readings(
    range_m: list[float] | np.ndarray,
    theta_rad: list[float] | np.ndarray,
    x_m: list[float] | np.ndarray,
    y_m: list[float] | np.ndarray,
    sensor: RangeSensor = LASER,
) -> SensorReadings:
    n = len(range_m)
    return SensorReadings(
        stamp_ns=np.arange(n, dtype=np.int64),
        sensor=np.zeros(n, dtype=np.int32),
        range_m=np.asarray(range_m, dtype=np.float64),
        x_m=np.asarray(x_m, dtype=np.float64),
        y_m=np.asarray(y_m, dtype=np.float64),
        theta_rad=np.asarray(theta_rad, dtype=np.float64),
        sensors=(sensor,),
    )


def run(
    r: SensorReadings, params: RayParams | None = None, spec: GridSpec = SPEC
) -> tuple[np.ndarray, np.ndarray, int]:
    grid = LogOddsAccumulator(spec)
    updates = RayModel(params or RayParams(), spec.resolution_m).accumulate(grid, r)
    return grid.log_odds(), grid.observations(), updates


L_FREE = logodds(RayParams().p_free)
L_OCC = logodds(RayParams().p_occupied)


@pytest.mark.parametrize(
    ("theta", "step"),
    [(0.0, (0, 1)), (math.pi / 2, (1, 0)), (math.pi, (0, -1)), (-math.pi / 2, (-1, 0))],
)
def test_axis_ray_is_free_then_one_occupied_cell(theta: float, step: Cell) -> None:
    # from the centre of cell (row 15, col 20), 1.0 m = 10 cells
    lo, obs, updates = run(readings([1.0], [theta], [0.05], [0.05]))
    free = {(15 + k * step[0], 20 + k * step[1]) for k in range(10)}
    end = (15 + 10 * step[0], 20 + 10 * step[1])
    assert updates == 11 == int(obs.sum())
    assert lo[end] == pytest.approx(L_OCC)
    for cell in free:
        assert lo[cell] == pytest.approx(L_FREE)
    touched = {(int(r), int(c)) for r, c in zip(*np.nonzero(obs), strict=True)}
    assert touched == free | {end}, "nothing beside or beyond the ray"


def test_diagonal_ray_is_a_staircase_ending_in_one_occupied_cell() -> None:
    # 45 degrees from the centre of cell (15, 20): through the corners of the diagonal cells
    lo, obs, _ = run(readings([math.sqrt(2.0)], [math.pi / 4], [0.05], [0.05]))
    end = (25, 30)
    occupied = {(int(r), int(c)) for r, c in zip(*np.nonzero(lo > 0), strict=True)}
    free = {(int(r), int(c)) for r, c in zip(*np.nonzero(lo < 0), strict=True)}
    assert occupied == {end}
    assert lo[end] == pytest.approx(L_OCC)
    assert {(15 + k, 20 + k) for k in range(10)} <= free
    # besides the diagonal, at most one of the two cells beside each corner, none past the end
    assert all(abs((r - 15) - (c - 20)) <= 1 and r <= 25 and c <= 30 for r, c in free)
    assert len(free) <= 20
    assert np.allclose(lo[lo < 0], L_FREE)
    assert set(zip(*np.nonzero(obs), strict=True)) == free | occupied


def test_ray_at_an_angle_matches_the_traversal() -> None:
    theta, z = 0.3, 1.37
    lo, obs, _ = run(readings([z], [theta], [-0.72], [0.11]))
    x1, y1 = -0.72 + z * math.cos(theta), 0.11 + z * math.sin(theta)
    cells = traversed(SPEC, -0.72, 0.11, x1, y1)
    c, r = SPEC.world_to_cell(np.array([x1]), np.array([y1]))
    end = (int(r[0]), int(c[0]))
    assert end in cells
    assert {(int(a), int(b)) for a, b in zip(*np.nonzero(obs), strict=True)} == cells
    assert lo[end] == pytest.approx(L_OCC)
    assert all(lo[cell] == pytest.approx(L_FREE) for cell in cells - {end})


def test_no_echo_gives_free_space_only_up_to_the_max_range() -> None:
    short = RangeSensor("l", 0.0, 0.0, 0.0, 0.0, 0.02, 1.5, kind="laser")
    lo, obs, _ = run(readings([short.max_range_m], [0.0], [-1.95], [0.05], short))
    assert lo.max() == 0.0, "a max-range reading must never give occupied evidence"
    # the whole ray is free, the cell holding its far end too: cols 0 .. 15 of row 15
    assert np.allclose(lo[15, :16], L_FREE)
    assert obs[15, :16].tolist() == [1] * 16
    assert obs.sum() == 16


def test_no_echo_free_range_limits_and_zero_ignores() -> None:
    lo, obs, _ = run(
        readings([LASER.max_range_m], [0.0], [-1.95], [0.05]), RayParams(0.7, 0.4, 1.0)
    )
    assert obs.sum() == 11 and obs[15, :11].all()  # 1.0 m from x = -1.95 ends in col 10
    assert np.allclose(lo[15, :11], logodds(0.4))
    lo, obs, updates = run(
        readings([LASER.max_range_m], [0.0], [-1.95], [0.05]), RayParams(no_echo_free_m=0.0)
    )
    assert updates == 0 and not lo.any() and not obs.any()


def test_rays_entering_and_leaving_the_grid_are_cut_to_it() -> None:
    rng = np.random.default_rng(7)
    n = 3000
    r = readings(
        rng.uniform(0.05, 7.99, n),
        rng.uniform(-math.pi, math.pi, n),
        rng.uniform(-4.0, 4.0, n),
        rng.uniform(-3.0, 3.0, n),
    )
    big = GridSpec(-13.0, -12.0, 0.1, 260, 240)  # holds every ray; SPEC is its window
    lo_big, obs_big, updates_big = run(r, spec=big)
    lo, obs, updates = run(r)
    window = (slice(105, 105 + SPEC.height), slice(110, 110 + SPEC.width))
    assert np.array_equal(obs, obs_big[window])
    assert np.allclose(lo, lo_big[window], atol=1e-9)
    assert updates == int(obs.sum()) < updates_big == int(obs_big.sum())


def test_accumulation_does_not_depend_on_reading_order_or_batches() -> None:
    rng = np.random.default_rng(11)
    n = 500
    args = (
        rng.uniform(0.05, 2.5, n),
        rng.uniform(-math.pi, math.pi, n),
        rng.uniform(-1.5, 1.5, n),
        rng.uniform(-1.0, 1.0, n),
    )
    lo, obs, _ = run(readings(*args))
    perm = rng.permutation(n)
    grid = LogOddsAccumulator(SPEC)
    model = RayModel(RayParams(), SPEC.resolution_m)
    for chunk in np.array_split(perm, 7):
        model.accumulate(grid, readings(*(a[chunk] for a in args)))
    assert np.array_equal(grid.observations(), obs)
    assert np.allclose(grid.log_odds(), lo, atol=1e-12)


def test_bounds_hold_start_points_and_echoes_not_free_only_ends() -> None:
    model = RayModel(RayParams(no_echo_free_m=2.0), 0.05)
    r = readings([1.0, LASER.max_range_m], [0.0, math.pi / 2], [0.5, -1.0], [0.0, 0.25])
    # the no-echo beam's free segment (to y = 2.25) is clipped to the map, never grows it
    assert model.bounds(r) == pytest.approx((-1.0, 0.0, 1.5, 0.25))


def test_max_range_cuts_long_readings_to_free_space() -> None:
    model = RayModel(RayParams(max_range_m=2.0), 0.05)
    r = readings([1.0, 3.0], [0.0, 0.0], [0.0, 0.0], [0.0, 1.0])
    seg = model.segments(r)
    assert seg.echo.tolist() == [True, False]  # cut: no wall at its end
    assert seg.x1_m.tolist() == pytest.approx([1.0, 2.0])
    assert model.bounds(r) == pytest.approx((0.0, 0.0, 1.0, 1.0))


@pytest.mark.parametrize(
    "kwargs",
    [{"p_occupied": 0.5}, {"p_occupied": 1.0}, {"p_free": 0.5}, {"p_free": 0.0},
     {"no_echo_free_m": -1.0}, {"no_echo_free_m": math.nan}, {"max_range_m": 0.0},
     {"max_range_m": math.nan}],
)  # fmt: skip
def test_params_are_validated(kwargs: dict[str, float]) -> None:
    with pytest.raises(ValueError):
        RayParams(**kwargs)


# --- through the pipeline ----------------------------------------------------------------------

HALF_ROOM_M = 2.0  # walls on x = +-2 and y = +-2


def distance_to_wall(x: float, y: float, theta: np.ndarray) -> np.ndarray:
    """Range from (x, y) inside the room to its walls along directions ``theta``."""
    c, s = np.cos(theta), np.sin(theta)
    with np.errstate(divide="ignore"):
        tx = np.where(c != 0, (np.sign(c) * HALF_ROOM_M - x) / c, np.inf)
        ty = np.where(s != 0, (np.sign(s) * HALF_ROOM_M - y) / s, np.inf)
    return np.minimum(tx, ty)


def test_a_laser_scan_maps_the_walls_of_a_room() -> None:
    yaws = np.radians(np.arange(-90, 91, dtype=np.float64))  # 181 beams, 1 degree apart
    sensors = tuple(
        RangeSensor(f"laser{k}", 0.0, 0.0, float(yaw), 0.0, 0.02, 8.0, kind="laser")
        for k, yaw in enumerate(yaws)
    )
    poses = [
        (x, y, heading)
        for x in (-0.5, 0.5)
        for y in (-0.5, 0.5)
        for heading in (0.0, math.pi / 2, math.pi, -math.pi / 2)
    ]
    stamps = np.arange(len(poses), dtype=np.int64) * 100_000_000
    track = PoseTrack(stamps, *(np.array(v, dtype=np.float64) for v in zip(*poses, strict=True)))
    ranges = np.concatenate([distance_to_wall(x, y, h + yaws) for x, y, h in poses])
    log = RangeLog(
        "room.csv",
        track,
        RangeReadings(
            np.repeat(stamps, len(yaws)),
            np.tile(np.arange(len(yaws), dtype=np.int32), len(poses)),
            ranges,
        ),
        tuple(s.name for s in sensors),
        sensors=sensors,
    )
    result = build_map(log, None, BuildOptions(resolution_m=0.05))
    spec, prob = result.map.spec, result.map.prob
    res = spec.resolution_m
    rows, cols = np.indices(prob.shape)
    cx, cy = spec.cell_center(cols, rows)
    to_wall = np.minimum(HALF_ROOM_M - np.abs(cx), HALF_ROOM_M - np.abs(cy))  # < 0 outside

    # the walls are the cells with more hits than misses (docs/sensor-model.md)
    occupied = prob > 0.5
    assert occupied.sum() >= 0.8 * 4 * 2 * HALF_ROOM_M / res, "the walls are mapped"
    assert np.all(np.abs(to_wall[occupied]) <= res + 1e-9), "occupied only on the walls"
    assert np.all(np.isnan(prob[to_wall < -res])), "nothing seen behind the walls"
    interior = to_wall > 1.5 * res
    assert np.all(prob[interior] <= 0.25), "the whole interior is free"
    assert result.sync.used == 181 * len(poses)


def test_sonar_and_laser_readings_share_one_map() -> None:
    sonar = RangeSensor("sonar", 0.0, 0.0, math.pi, math.radians(25), 0.15, 5.0)
    laser = RangeSensor("laser", 0.0, 0.0, 0.0, 0.0, 0.02, 8.0, kind="laser")
    poses = PoseTrack(np.array([0, 10], dtype=np.int64), np.zeros(2), np.zeros(2), np.zeros(2))
    stamps = np.array([0, 0, 10, 10], dtype=np.int64)
    log = RangeLog(
        "mixed.csv",
        poses,
        RangeReadings(stamps, np.array([0, 1, 0, 1], dtype=np.int32), np.array([2.0, 3.0] * 2)),
        ("sonar", "laser"),
        sensors=(sonar, laser),
    )
    result = build_map(log, None, BuildOptions())
    spec, prob = result.map.spec, result.map.prob
    assert spec.origin_x_m <= -2.05 and spec.origin_x_m + spec.width * spec.resolution_m >= 3.0
    col, row = spec.world_to_cell(np.array([3.0, 1.0, -2.0, -1.0]), np.array([0.0] * 4))
    laser_end, laser_free, sonar_arc, sonar_free = prob[row, col]
    assert laser_end > 0.5 > laser_free
    assert sonar_arc > 0.5 > sonar_free
    # the laser marks one cell on its axis; the sonar an arc of cells around its axis
    assert np.count_nonzero(prob[:, col[0]] > 0.5) == 1
    assert np.count_nonzero(prob[:, col[2]] > 0.5) > 3


def test_large_batches_are_split_without_changing_the_result(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    rng = np.random.default_rng(5)
    n = 400
    r = readings(
        rng.uniform(0.05, 3.0, n),
        rng.uniform(-math.pi, math.pi, n),
        rng.uniform(-1.5, 1.5, n),
        rng.uniform(-1.0, 1.0, n),
    )
    lo, obs, updates = run(r)
    monkeypatch.setattr("gridmap_cli.mapping.models.ray._ROWS_PER_CHUNK", 50)
    lo_split, obs_split, updates_split = run(r)
    assert updates_split == updates
    assert np.array_equal(obs_split, obs)
    assert np.allclose(lo_split, lo, atol=1e-12)
