"""Quality without ground truth (gridmap_cli.evaluation.quality): the log's own score ranks the
maps of one log as their NLL against the truth does, and its parts are what they say."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest

from gridmap_cli.evaluation.evaluate import (
    ProbabilityMap,
    evaluate_map,
    odometry_frame_in_world,
    sensed_region,
)
from gridmap_cli.evaluation.quality import (
    EchoConsistency,
    Quality,
    closure_consistency,
    echo_consistency,
    map_readings,
    quality_table,
    spread_summary,
    spread_timeline,
)
from gridmap_cli.evaluation.revisits import (
    Revisits,
    RevisitScore,
    echo_displacement,
    graph_revisits,
    map_revisits,
    relative_poses,
    score_track,
)
from gridmap_cli.geometry import compose, inverse
from gridmap_cli.mapping.grid import GridSpec, OccupancyMap
from gridmap_cli.mapping.pipeline import BuildOptions, build_map
from gridmap_cli.poses.correction.pose_graph import Edge
from gridmap_cli.poses.correction.scan_match import ScanMatch, corrected_track, match_log
from gridmap_cli.poses.sync import interpolate_pose, sensors_for_log
from gridmap_cli.poses.uncertainty.pose_uncertainty import PoseUncertainty
from gridmap_cli.records import PoseTrack, RangeLog
from tests.test_scan_match import laser_robot, room_world
from tests.test_scan_match import run as simulate_run

if TYPE_CHECKING:
    from gridmap_cli.poses.correction.slam import SlamResult

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
LOOP = [[2, 1.5], [10, 1.5], [10, 6.5], [2, 6.5], [2, 1.5]]
SOURCES = ("odometry", "scan-matched", "slam")


@pytest.fixture(scope="module")
def loop() -> tuple[RangeLog, SlamResult, ScanMatch]:
    """The drifting laser loop, its pose graph and its open-loop scan match."""
    from gridmap_cli.poses.correction.slam import slam_log

    log = simulate_run(room_world(), LOOP, drift=3.0)
    robot = laser_robot()
    return log, slam_log(log, robot), match_log(log, robot)


def posed_logs(loop: tuple[RangeLog, SlamResult, ScanMatch]) -> dict[str, RangeLog]:
    """The log with the poses of each source, as build --pose maps it."""
    log, slam, match = loop
    return {
        "odometry": log,
        "scan-matched": dataclasses.replace(log, poses=corrected_track(log.poses, match)),
        "slam": dataclasses.replace(log, poses=corrected_track(log.poses, slam.match)),
    }


@pytest.fixture(scope="module")
def scored(
    loop: tuple[RangeLog, SlamResult, ScanMatch],
) -> dict[str, tuple[float, EchoConsistency]]:
    """Per pose source: NLL against the simulated world, and the echo consistency."""
    log = loop[0]
    world = room_world()
    robot = laser_robot()
    assert log.truth is not None
    region = sensed_region(world, log.truth, sensors_for_log(log, robot))
    placed = odometry_frame_in_world(log)
    out = {}
    options = BuildOptions()
    for source, posed in posed_logs(loop).items():
        omap = build_map(posed, robot, options).map
        pmap = ProbabilityMap.from_occupancy_map(omap, 0.65)
        nll = evaluate_map(pmap, world.occupied, world.spec, region, placed).nll
        echoes = echo_consistency(omap, map_readings(posed, robot, options), 0.65, 0.25)
        assert echoes is not None
        out[source] = (nll, echoes)
    return out


def test_the_echo_share_ranks_the_maps_as_the_truth_does(
    scored: dict[str, tuple[float, EchoConsistency]],
) -> None:
    nll = {s: scored[s][0] for s in SOURCES}
    share = {s: scored[s][1].in_free for s in SOURCES}
    # the simulated loop drifts: the odometry's map is the worst against the truth, and by the
    # log alone, with no truth
    assert nll["odometry"] > max(nll["scan-matched"], nll["slam"]), nll
    assert share["odometry"] > max(share["scan-matched"], share["slam"]), (share, nll)
    # the two corrected maps are ranked alike wherever the truth tells them apart
    if abs(nll["scan-matched"] - nll["slam"]) > 0.1 * nll["slam"]:
        assert sorted(SOURCES, key=nll.__getitem__) == sorted(SOURCES, key=share.__getitem__)


def test_echoes_are_looked_up_where_they_end() -> None:
    """Laser echoes ending in a free cell, an occupied one, an unknown one and outside the map,
    and a no-echo reading: only the first two count."""
    from gridmap_cli.poses.sync import SensorReadings
    from gridmap_cli.robot import RangeSensor

    spec = GridSpec(0.0, 0.0, 1.0, 4, 1)
    omap = OccupancyMap(spec, np.array([[0.1, 0.5, 0.9, np.nan]]))
    laser = RangeSensor("laser_0", 0.0, 0.0, 0.0, 0.0, 0.1, 10.0, kind="laser")
    n = 5
    readings = SensorReadings(
        stamp_ns=np.arange(n, dtype=np.int64),
        sensor=np.zeros(n, np.int32),
        range_m=np.array([0.5, 2.0, 3.5, 5.0, 10.0]),
        x_m=np.zeros(n),
        y_m=np.full(n, 0.5),
        theta_rad=np.zeros(n),
        sensors=(laser,),
    )
    e = echo_consistency(omap, iter([readings]), 0.65, 0.25)
    assert e is not None
    assert (e.echoes, e.in_free, e.in_occupied) == (2, 0.5, 0.5)


def test_closures_are_whitened_by_their_own_noise() -> None:
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    # a closure that says node 2 lies 2.2 m from node 0, with 0.1 m noise: residual 2 sigma in x
    closure = Edge(0, 2, 2.2, 0.0, 0.0, 0.1, 0.1, closure=True)
    chain = Edge(0, 1, 1.0, 0.0, 0.0, 0.1, 0.1)
    c = closure_consistency(poses, [chain, closure])
    assert c is not None and c.closures == 1
    assert c.median_nees == pytest.approx(4.0, rel=1e-6)
    assert closure_consistency(poses, [chain]) is None


def test_the_spread_summary_says_when_the_spread_passes_each_threshold() -> None:
    stamps = np.array([0, 60, 120, 180], dtype=np.int64) * 1_000_000_000
    sigma = np.array([0.0, 0.3, 0.8, 1.5])
    cov = np.zeros((4, 3, 3))
    cov[:, 0, 0] = sigma**2
    cov[:, 1, 1] = (0.5 * sigma) ** 2
    unc = PoseUncertainty(stamps, np.zeros(4), np.zeros(4), cov)
    crossing, duration, largest = spread_timeline(unc)
    assert crossing == pytest.approx((60.0, 120.0, 180.0)) and duration == pytest.approx(180.0)
    assert largest == pytest.approx(1.5)
    layer = np.array([[0.05, 0.2, np.nan], [0.7, 2.0, 0.1]])
    summary = spread_summary(layer, unc)
    assert summary.known_cells == 5 and summary.shares == (0.4, 0.6, 0.8)
    assert "beyond 3.0 min of 3.0 min the position spread exceeds 1 m" in summary.line()
    # a log whose stamps do not advance (every record a microsecond apart) says it in metres
    still = PoseUncertainty(stamps // 60_000_000, np.array([0.0, 4.0, 9.0, 9.0]),
                            np.array([0.0, 0.0, 0.0, 3.0]), cov)  # fmt: skip
    summary = spread_summary(layer, still)
    assert not summary.stamps_advance and summary.driven_m == pytest.approx(12.0)
    assert "beyond 12 m driven of 12 m the position spread exceeds 1 m" in summary.line()
    assert summary.as_dict()["exceeds_after_m"] == {"0.1": 4.0, "0.5": 9.0, "1": 12.0}


@pytest.mark.skipif(not (DATA / "carmen").is_dir(), reason="../shared/data is not present")
def test_on_aces_the_pose_graph_contradicts_fewer_echoes_than_the_odometry() -> None:
    """A real log: the map of the raw odometry contradicts more of its own echoes than the
    pose graph's (whose NLL against the corrected-pose reference is the lower, docs/quality.md)."""
    from gridmap_cli.readers import read_logs
    from gridmap_cli.readers.options import ReadOptions

    log = read_logs((DATA / "carmen" / "aces-corrected.log.gz",), None, ReadOptions())
    from gridmap_cli.poses.correction.slam import slam_log

    slam = slam_log(log, None)
    options = BuildOptions()
    shares = {}
    for source, posed in (
        ("odometry", log),
        ("slam", dataclasses.replace(log, poses=corrected_track(log.poses, slam.match))),
    ):
        omap = build_map(posed, None, options).map
        e = echo_consistency(omap, map_readings(posed, None, options), 0.65, 0.25)
        assert e is not None
        shares[source] = e.in_free
    assert shares["odometry"] > shares["slam"] + 0.1, shares


def test_evaluate_without_truth_reports_what_the_log_tells(tmp_path: Path, room_csv: Path) -> None:
    from tests.helpers import run

    cal = tmp_path / "odo.yaml"
    cal.write_text("gridmap-odometry-error: 1\nrange_m_per_sqrt_m: 0.05\n")
    out = tmp_path / "m.png"
    code, _, stderr = run("build", str(room_csv), "-o", str(out), "--map-mode", "scale")
    assert code == 0, stderr
    yaml_path = str(out.with_suffix(".yaml"))
    code, stdout, stderr = run("evaluate", yaml_path, "--log", str(room_csv), "--odometry-error",
                               str(cal), "--json")  # fmt: skip
    assert code == 0, stderr
    doc = json.loads(stdout)
    assert doc["pose"] == "odometry" and doc["spread"]["known_cells"] > 0
    assert doc["echo_consistency"] is None and doc["closures"] is None  # sonar, no graph
    assert doc["revisits"] is None
    code, stdout, _ = run("evaluate", yaml_path, "--log", str(room_csv))
    assert code == 0 and "pose spread           n/a" in stdout and "echo consistency" in stdout
    assert "revisits              n/a" in stdout


def test_evaluate_without_truth_needs_the_log_and_draws_nothing(
    tmp_path: Path, room_csv: Path
) -> None:
    from tests.helpers import names, run

    out = tmp_path / "m.png"
    assert run("build", str(room_csv), "-o", str(out))[0] == 0
    before = names(tmp_path)
    code, _, stderr = run("evaluate", str(out.with_suffix(".yaml")))
    assert code == 2 and "give --truth WORLD.yaml" in stderr and "or --log LOG" in stderr
    plot = tmp_path / "p.png"
    code, _, stderr = run("evaluate", str(out.with_suffix(".yaml")), "--log", str(room_csv),
                          "--plot", str(plot))  # fmt: skip
    assert code == 2 and "--plot and --spread-plot draw the map against --truth" in stderr
    assert names(tmp_path) == before


@pytest.fixture(scope="module")
def loop_revisits(
    loop: tuple[RangeLog, SlamResult, ScanMatch],
) -> tuple[RangeLog, Revisits, dict[str, RevisitScore]]:
    """The drifting loop, the revisits its pose graph found, and each source's map scored on
    them (the graph's own track on the closures held out of its solve)."""
    log, slam, _ = loop
    revisits = graph_revisits(slam, log, laser_robot())
    assert revisits is not None and revisits.predicted is not None
    scores = {}
    for source, posed in posed_logs(loop).items():
        score = map_revisits(revisits, posed.poses, graph_track=source == "slam")
        assert score is not None
        scores[source] = score
    return log, revisits, scores


def test_the_revisits_rank_the_drifting_loop_as_the_truth_does(
    loop_revisits: tuple[RangeLog, Revisits, dict[str, RevisitScore]],
    scored: dict[str, tuple[float, EchoConsistency]],
) -> None:
    _, revisits, scores = loop_revisits
    apart = {s: scores[s].mean_m for s in SOURCES}
    nll = {s: scored[s][0] for s in SOURCES}
    assert scores["slam"].held_out and not scores["odometry"].held_out
    assert all(scores[s].relations == len(revisits) for s in SOURCES)
    # the odometry drifted metres and degrees around the loop; its two visits of the start
    # lie far apart, the corrected tracks' within a few centimetres
    assert apart["odometry"] > 10 * max(apart["scan-matched"], apart["slam"]), apart
    assert apart["odometry"] > 0.5 and scores["odometry"].rot_mean_deg > 5.0
    assert nll["odometry"] > max(nll["scan-matched"], nll["slam"])


def test_the_revisits_see_a_bend_the_echo_share_does_not(
    loop_revisits: tuple[RangeLog, Revisits, dict[str, RevisitScore]],
) -> None:
    """Two maps of the loop: one bent as a whole (5 degrees of heading gained evenly along the
    path, every step exact, so each place is crisp), one blurred in place (every pose off by
    3 cm and 1 degree at random, no drift). The truth prefers the blurred map; so do the
    revisits; the echo share, which counts only local contradictions, prefers the bent one."""
    log, revisits, _ = loop_revisits
    world = room_world()
    robot = laser_robot()
    assert log.truth is not None
    region = sensed_region(world, log.truth, sensors_for_log(log, robot))
    stamps = log.poses.stamp_ns
    tx, ty, tth, _ = interpolate_pose(log.truth, stamps)
    ix, iy, ith = inverse(tx[:-1], ty[:-1], tth[:-1])
    dx, dy, dth = compose(ix, iy, ith, tx[1:], ty[1:], tth[1:])
    step = np.hypot(dx, dy)
    turn = dth + math.radians(5.0) * step / step.sum()
    x, y, th = [float(tx[0])], [float(ty[0])], [float(tth[0])]
    for k in range(len(step)):
        a, b, c = compose(x[-1], y[-1], th[-1], dx[k], dy[k], turn[k])
        x.append(float(a))
        y.append(float(b))
        th.append(float(c))
    bent = PoseTrack(stamp_ns=stamps, x_m=np.array(x), y_m=np.array(y), theta_rad=np.array(th))
    rng = np.random.default_rng(0)
    n = len(stamps)
    blurred = PoseTrack(
        stamp_ns=stamps,
        x_m=tx + rng.normal(0.0, 0.03, n),
        y_m=ty + rng.normal(0.0, 0.03, n),
        theta_rad=tth + np.radians(rng.normal(0.0, 1.0, n)),
    )
    options = BuildOptions()
    nll, share, apart = {}, {}, {}
    for name, track in (("bent", bent), ("blurred", blurred)):
        posed = dataclasses.replace(log, poses=track)
        omap = build_map(posed, robot, options).map
        pmap = ProbabilityMap.from_occupancy_map(omap, 0.65)
        nll[name] = evaluate_map(pmap, world.occupied, world.spec, region).nll  # world frame
        echoes = echo_consistency(omap, map_readings(posed, robot, options), 0.65, 0.25)
        assert echoes is not None
        share[name] = echoes.in_free
        apart[name] = score_track(track, revisits).mean_m
    assert nll["bent"] > 1.5 * nll["blurred"], nll
    assert apart["bent"] > 2 * apart["blurred"], apart
    assert share["bent"] < share["blurred"], share  # the blind spot the revisits cover


def test_the_echo_displacement_is_the_mean_over_the_echoes() -> None:
    """The closed form against the echoes moved one by one."""
    rng = np.random.default_rng(1)
    points = [rng.uniform(-8.0, 8.0, (50, 2)) for _ in range(4)]
    error = np.column_stack([rng.normal(0, 0.3, 4), rng.normal(0, 0.3, 4), rng.normal(0, 0.1, 4)])
    mean = np.array([p.mean(axis=0) for p in points])
    square = np.array([(p**2).sum(axis=1).mean() for p in points])
    got = echo_displacement(error, mean, square)
    for k, p in enumerate(points):
        px, py, _ = compose(error[k, 0], error[k, 1], error[k, 2], p[:, 0], p[:, 1], 0.0)
        moved = np.hypot(px - p[:, 0], py - p[:, 1])
        assert got[k] == pytest.approx(math.sqrt(float((moved**2).mean())), rel=1e-9)


def test_a_false_closure_moves_two_tracks_apart_by_no_more_than_they_disagree() -> None:
    """Why the mean may rank the maps of one log: on any relation, however wrong the registered
    pose, two tracks' displacements differ by at most how far the tracks place the scan apart."""
    rng = np.random.default_rng(2)
    n = 200
    points = [rng.uniform(-8.0, 8.0, (30, 2)) for _ in range(n)]
    mean = np.array([p.mean(axis=0) for p in points])
    square = np.array([(p**2).sum(axis=1).mean() for p in points])

    def poses(scale: float) -> np.ndarray:
        return np.column_stack([rng.normal(0, scale, (n, 2)), rng.normal(0, scale / 3, n)])

    registered, a, b = poses(5.0), poses(0.5), poses(0.5)  # a wild registration, two tracks
    d_a = echo_displacement(relative_poses(registered, a), mean, square)
    d_b = echo_displacement(relative_poses(registered, b), mean, square)
    apart = echo_displacement(relative_poses(b, a), mean, square)
    assert np.all(np.abs(d_a - d_b) <= apart + 1e-9)
    assert np.abs(d_a - d_b).max() > 0.5 * apart.max()  # the bound is reached, not loose


def test_the_mean_sees_a_break_few_revisits_straddle() -> None:
    """A track exact but for one turn it lost at one moment, straddled by 3 of 10 revisits,
    against one blurred everywhere by 0.1 m: the median calls the broken track the better, the
    mean does not (every pose after the break is off by metres)."""
    stamps = np.arange(0, 100, dtype=np.int64)
    truth = PoseTrack(stamps, np.linspace(0.0, 50.0, 100), np.zeros(100), np.zeros(100))
    t1 = np.array([10, 20, 30, 40, 50, 60, 70, 5, 15, 25], dtype=np.int64)
    t2 = np.array([12, 22, 32, 42, 52, 62, 72, 95, 85, 90], dtype=np.int64)
    x1, y1, th1, _ = interpolate_pose(truth, t1)
    x2, y2, th2, _ = interpolate_pose(truth, t2)
    revisits = Revisits(
        t1_ns=t1,
        t2_ns=t2,
        relative=relative_poses(np.column_stack([x1, y1, th1]), np.column_stack([x2, y2, th2])),
        echo_mean_m=np.zeros((10, 2)),
        echo_square_m2=np.full(10, 9.0),
    )
    x, y, th = truth.x_m.copy(), truth.y_m.copy(), truth.theta_rad.copy()
    after = stamps >= 80  # turned by 30 degrees about the pose at the break
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    dx, dy = x[after] - x[80], y[after] - y[80]
    x[after], y[after], th[after] = (
        x[80] + c * dx - s * dy,
        y[80] + s * dx + c * dy,
        th[after] + 0.5236,
    )
    broken = PoseTrack(stamps, x, y, th)
    rng = np.random.default_rng(3)
    blurred = PoseTrack(stamps, truth.x_m + rng.normal(0, 0.1, 100), rng.normal(0, 0.1, 100),
                        np.radians(rng.normal(0, 1.0, 100)))  # fmt: skip
    b, u = score_track(broken, revisits), score_track(blurred, revisits)
    assert b.median_m < u.median_m  # the median is blind to the break
    assert b.mean_m > 2 * u.mean_m, (b.mean_m, u.mean_m)


def test_a_track_is_scored_on_the_relations_it_covers() -> None:
    """A track that covers one of two relations: one scored, one skipped; a pure turn of the
    second scan moves its echoes by their distance times 2 sin(theta / 2)."""
    revisits = Revisits(
        t1_ns=np.array([0, 0], dtype=np.int64),
        t2_ns=np.array([10, 50], dtype=np.int64),
        relative=np.zeros((2, 3)),
        echo_mean_m=np.zeros((2, 2)),
        echo_square_m2=np.full(2, 4.0),  # every echo 2 m away
    )
    track = PoseTrack(
        stamp_ns=np.array([0, 20], dtype=np.int64),
        x_m=np.zeros(2),
        y_m=np.zeros(2),
        theta_rad=np.array([0.0, 0.2]),
    )
    s = score_track(track, revisits)
    assert (s.relations, s.skipped) == (1, 1)
    assert s.median_m == pytest.approx(2.0 * 2.0 * math.sin(0.05), rel=1e-9)
    assert s.rot_mean_deg == pytest.approx(math.degrees(0.1))


def test_build_json_and_evaluate_score_the_map_on_the_revisits(
    tmp_path: Path, loop: tuple[RangeLog, SlamResult, ScanMatch]
) -> None:
    """A slam build's quality block holds its revisits, held out of the graph's solve; evaluate
    of the odometry's map solves the graph for them and finds the odometry's visits apart."""
    from gridmap_cli.writers.csv_log import save_csv_log
    from tests.helpers import run

    log = dataclasses.replace(loop[0], metadata={**loop[0].metadata, "robot": "p3at-lms200"})
    csv = tmp_path / "run.csv"
    save_csv_log(log, csv)
    slam_map, odo_map = tmp_path / "slam.png", tmp_path / "odo.png"
    code, stdout, stderr = run("build", str(csv), "--pose", "slam", "-o", str(slam_map), "--json")
    assert code == 0, stderr
    graph = json.loads(stdout)["quality"]["revisits"]
    assert graph["held_out"] and graph["relations"] >= 1 and graph["mean_m"] < 0.1
    assert run("build", str(csv), "--pose", "odometry", "-o", str(odo_map))[0] == 0
    yaml_path = str(odo_map.with_suffix(".yaml"))
    code, stdout, stderr = run("evaluate", yaml_path, "--log", str(csv), "--pose", "odometry",
                               "--json")  # fmt: skip
    assert code == 0, stderr
    odo = json.loads(stdout)["revisits"]
    assert not odo["held_out"] and odo["relations"] == graph["relations"]
    assert odo["mean_m"] > 10 * graph["mean_m"]


def test_the_table_says_how_far_apart_the_visits_are(
    loop_revisits: tuple[RangeLog, Revisits, dict[str, RevisitScore]],
) -> None:
    _, _, scores = loop_revisits
    odo, graph = scores["odometry"], scores["slam"]
    text = quality_table("m.yaml", "run.csv", "odometry", Quality(None, None, None, odo))
    assert "places the scans found twice (the map's track)" in text
    assert f"mean {odo.mean_m:.3f} m between" in text and f"median {odo.median_m:.3f} m" in text
    text = quality_table("m.yaml", "run.csv", "slam", Quality(None, None, None, graph))
    assert "held out of the graph's solve" in text
    text = quality_table("m.yaml", "run.csv", "odometry", Quality(None, None, None))
    assert "revisits              n/a" in text
