"""evaluate: scores computed by hand on a 3 x 3 map, frames, regions, files and bad input."""

from __future__ import annotations

import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from gridmap_cli.evaluation.evaluate import (
    EvaluationError,
    ProbabilityMap,
    evaluate_map,
    load_probability_map,
    map_in_world,
    odometry_frame_in_world,
    sensed_region,
)
from gridmap_cli.evaluation.plot import UNKNOWN_RGB, map_rgb
from gridmap_cli.mapping.grid import GridSpec, OccupancyMap
from gridmap_cli.mapping.mapfile import load_map
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import RangeSensor
from gridmap_cli.sim.world import World
from gridmap_cli.writers.csv_log import save_csv_log
from gridmap_cli.writers.map_image import map_yaml_text, write_map
from tests.helpers import log_with_truth, names, run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"

# A 3 x 3 world at 1 m whose right column is a wall (rows listed bottom first).
WORLD3 = GridSpec(0.0, 0.0, 1.0, 3, 3)
WALLS3 = np.array([[0, 0, 1], [0, 0, 1], [0, 0, 1]], dtype=bool)
# The map: row 1 column 1 unknown (counts as 0.5).
PROB3 = np.array([[0.8, 0.2, 0.9], [0.1, np.nan, 0.7], [0.4, 0.1, 0.2]])


def test_three_by_three_by_hand() -> None:
    e = evaluate_map(ProbabilityMap(WORLD3, PROB3, 0.65), WALLS3, WORLD3)
    assert (e.cells, e.occupied_cells) == (9, 3)
    # NLL, cell by cell (-ln(1 - p) for free, -ln p for wall cells):
    #   row 0: -ln 0.2 = 1.6094379, -ln 0.8 = 0.2231436, -ln 0.9 = 0.1053605
    #   row 1: -ln 0.9 = 0.1053605, -ln 0.5 = 0.6931472, -ln 0.7 = 0.3566749
    #   row 2: -ln 0.6 = 0.5108256, -ln 0.9 = 0.1053605, -ln 0.2 = 1.6094379
    #   sum 5.3187486 / 9 = 0.5909721
    assert e.nll == pytest.approx(5.3187486 / 9, abs=1e-7)
    # Brier: (0.64 + 0.04 + 0.01) + (0.01 + 0.25 + 0.09) + (0.16 + 0.01 + 0.64) = 1.85 / 9
    assert e.brier == pytest.approx(1.85 / 9)
    # bins: [0.1, 0.2): 0.1, 0.1 (free, free); [0.2, 0.3): 0.2 free, 0.2 wall; 0.4 free;
    # 0.5 free; 0.7 wall; 0.8 free; 0.9 wall. ECE = (2 * 0.1 + 2 * |0.2 - 0.5| + 0.4 + 0.5
    # + 0.3 + 0.8 + 0.1) / 9 = 2.9 / 9
    counts = [b.count for b in e.reliability]
    assert counts == [0, 2, 2, 0, 1, 1, 0, 1, 1, 1]
    assert e.reliability[2].mean_predicted == pytest.approx(0.2)
    assert e.reliability[2].observed_frequency == pytest.approx(0.5)
    assert math.isnan(e.reliability[0].mean_predicted)
    assert e.ece == pytest.approx(2.9 / 9)
    # occupied at p >= 0.65: 0.8 (two cells from the wall: wrong), 0.9 and 0.7 (on the wall).
    # precision 2/3; recall: the wall cell at p = 0.2 has the 0.7 cell next to it: 3/3
    assert e.predicted_occupied == 3
    assert e.precision == pytest.approx(2 / 3) and e.recall == 1.0
    assert e.f1 == pytest.approx(2 * (2 / 3) / (2 / 3 + 1))
    assert e.coverage == pytest.approx(8 / 9)


def test_nll_clips_certain_mistakes() -> None:
    # a trinary map states p = 0 and 1; one wrong certain cell costs ln 1000, not infinity
    prob = np.where(WALLS3, 1.0, 0.0)
    prob[0, 0] = 1.0
    e = evaluate_map(ProbabilityMap(WORLD3, prob, 0.65), WALLS3, WORLD3)
    assert e.nll == pytest.approx((8 * -math.log(0.999) + -math.log(0.001)) / 9)
    assert e.brier == pytest.approx(1 / 9)


def test_unknown_and_outside_count_as_one_half() -> None:
    unknown = ProbabilityMap(WORLD3, np.full((3, 3), np.nan), 0.65)
    far_away = ProbabilityMap(GridSpec(100.0, 100.0, 1.0, 3, 3), np.full((3, 3), 0.9), 0.65)
    for pmap in (unknown, far_away):
        e = evaluate_map(pmap, WALLS3, WORLD3)
        assert e.nll == pytest.approx(math.log(2))
        assert e.brier == pytest.approx(0.25)
        assert e.coverage == 0.0 and e.predicted_occupied == 0
        assert math.isnan(e.precision) and e.recall == 0.0
        # every cell in the 0.5 bin, a third of them occupied: ECE = |0.5 - 1/3|
        assert e.ece == pytest.approx(0.5 - 1 / 3)


def test_region_limits_the_cells_scored() -> None:
    region = np.zeros((3, 3), dtype=bool)
    region[0, :] = True  # bottom row: p 0.8, 0.2, 0.9 against free, free, wall
    e = evaluate_map(ProbabilityMap(WORLD3, PROB3, 0.65), WALLS3, WORLD3, region)
    assert e.cells == 3
    assert e.nll == pytest.approx((1.6094379 + 0.2231436 + 0.1053605) / 3, abs=1e-7)
    with pytest.raises(EvaluationError, match="holds no cell"):
        evaluate_map(ProbabilityMap(WORLD3, PROB3, 0.65), WALLS3, WORLD3, region & False)


# a 10 x 10 world at 1 m: an L of walls and a pillar
WORLD10 = GridSpec(0.0, 0.0, 1.0, 10, 10)
WALLS10 = np.zeros((10, 10), dtype=bool)
WALLS10[0, :] = True
WALLS10[:, 0] = True
WALLS10[6, 6] = True
START = (3.0, 2.0, math.pi / 2)  # the first true pose: the odometry frame in the world


def test_a_map_in_the_odometry_frame_scores_as_the_same_map_in_the_world_frame() -> None:
    rng = np.random.default_rng(3)
    world_prob = np.where(WALLS10, 0.9, 0.1) + rng.uniform(-0.05, 0.05, (10, 10))
    world_prob[8:, 8:] = np.nan
    in_world = ProbabilityMap(WORLD10, world_prob, 0.65)
    # The same map drawn in the odometry frame: map point (u, v) is world (3 - v, 2 + u), so
    # world cell centres land on map cell centres of a grid from (-2, -7).
    spec = GridSpec(-2.0, -7.0, 1.0, 10, 10)
    rows, cols = np.indices(spec.shape)
    u, v = spec.cell_center(cols, rows)
    wc, wr = WORLD10.world_to_cell(3.0 - v, 2.0 + u)
    in_odometry = ProbabilityMap(spec, world_prob[wr, wc], 0.65)
    a = evaluate_map(in_world, WALLS10, WORLD10)
    b = evaluate_map(in_odometry, WALLS10, WORLD10, map_to_world=START)
    assert a == b
    np.testing.assert_array_equal(
        map_in_world(in_odometry, WORLD10, START), map_in_world(in_world, WORLD10, (0, 0, 0))
    )
    # the evaluation carries the map on the world grid as scored, for drawing, not for JSON
    np.testing.assert_array_equal(b.p_world, map_in_world(in_odometry, WORLD10, START))
    assert "p_world" not in b.as_dict() and b.as_dict()["nll"] == b.nll
    # placed with the wrong pose it scores worse
    assert evaluate_map(in_odometry, WALLS10, WORLD10, map_to_world=(3.0, 2.0, 0.0)).nll > a.nll


def test_odometry_frame_in_world() -> None:
    # odometry starting at 0: the frame is the first true pose
    log = log_with_truth([START, (3.0, 3.0, math.pi / 2)], [(0, 0, 0), (1, 0, 0)])
    assert odometry_frame_in_world(log) == pytest.approx(START)
    # odometry starting at (1, 0, 0): the frame lies 1 m behind the robot, at world (3, 1)
    log = log_with_truth([START, (3.0, 3.0, math.pi / 2)], [(1, 0, 0), (2, 0, 0)])
    assert odometry_frame_in_world(log) == pytest.approx((3.0, 1.0, math.pi / 2))


def test_sensed_region_by_hand() -> None:
    # a 10 x 3 world with a wall in column 7; one pose at (1.5, 1.5) facing +x, one ray sensor
    walls = np.zeros((3, 10), dtype=bool)
    walls[:, 7] = True
    world = World(walls, GridSpec(0.0, 0.0, 1.0, 10, 3))
    pose = PoseTrack.from_rows(np.zeros(1, dtype=np.int64), [(1.5, 1.5, 0.0)])
    ray = RangeSensor("r", 0.0, 0.0, 0.0, 0.0, 0.0, 20.0, "laser")
    region = sensed_region(world, pose, [ray])
    assert np.flatnonzero(region[1]).tolist() == [1, 2, 3, 4, 5, 6, 7]  # up to the wall
    assert not region[0].any() and not region[2].any()
    short = RangeSensor("r", 0.0, 0.0, 0.0, 0.0, 0.0, 3.0, "laser")
    assert np.flatnonzero(sensed_region(world, pose, [short])[1]).tolist() == [1, 2, 3, 4]
    # a 90 degree cone fills a wedge: at column 4 (3 m ahead) it spans all three rows
    cone = RangeSensor("s", 0.0, 0.0, 0.0, math.pi / 2, 0.0, 20.0)
    wedge = sensed_region(world, pose, [cone])
    assert wedge[:, 4].all() and wedge[:, 7].all() and not wedge[:, 8:].any()


def test_sensed_region_takes_the_corners_a_ray_clips() -> None:
    # from (0.5, 0.5) at 35 degrees for 2.9 m in an empty world: the ray leaves cell (row 0,
    # col 0) through x = 1 at y = 0.85 into (0, 1), enters row 1 at x = 1.21, crosses x = 2 at
    # y = 1.55, enters row 2 at x = 2.64 and stops at (2.88, 2.16). Half-cell steps along it
    # (t = 0.5, 1.0) would skip (0, 1).
    world = World(np.zeros((5, 5), dtype=bool), GridSpec(0.0, 0.0, 1.0, 5, 5))
    pose = PoseTrack.from_rows(np.zeros(1, dtype=np.int64), [(0.5, 0.5, math.radians(35.0))])
    ray = RangeSensor("r", 0.0, 0.0, 0.0, 0.0, 0.0, 2.9, "laser")
    region = sensed_region(world, pose, [ray])
    assert [np.flatnonzero(row).tolist() for row in region] == [[0, 1], [1, 2], [2], [], []]


def _write_world(folder: Path, walls: np.ndarray, spec: GridSpec) -> Path:
    write_map(folder / "world.pgm", OccupancyMap(spec, walls.astype(np.float64)), mode="trinary")
    return folder / "world.yaml"


def test_cli_three_by_three_from_files(tmp_path: Path) -> None:
    world = _write_world(tmp_path, WALLS3, WORLD3)
    # a raw map whose values are round(100 p), as another tool may write one: these
    # probabilities come back exactly (gridmap's own raw maps write the cells they call
    # occupied and free as 100 and 0, which Nav2's costmap and AMCL read as walls and free)
    percent = np.where(np.isnan(PROB3), 255, np.rint(100 * np.nan_to_num(PROB3)))
    Image.fromarray(percent.astype(np.uint8)[::-1]).save(tmp_path / "map.pgm")
    (tmp_path / "map.yaml").write_text(map_yaml_text("map.pgm", "raw", WORLD3, 0.65, 0.25))
    code, out, err = run(
        "evaluate", str(tmp_path / "map.yaml"), "--truth", str(world), "--frame", "world", "--json"
    )
    assert code == 0, err
    doc = json.loads(out)
    assert doc["nll"] == pytest.approx(5.3187486 / 9, abs=1e-7)
    assert doc["brier"] == pytest.approx(1.85 / 9)
    assert doc["ece"] == pytest.approx(2.9 / 9)
    assert doc["f1"] == pytest.approx(0.8)
    assert doc["reliability"][0]["mean_predicted"] is None  # JSON has no NaN
    assert doc["region"] == "whole world"
    code, out, _ = run(
        "evaluate", str(tmp_path / "map.yaml"), "--truth", str(world), "--frame", "world"
    )
    assert code == 0
    assert "NLL (nats per cell)   0.5910" in out
    assert "scored over all 9 cells of the world (3 truly occupied)" in out


def test_scale_maps_keep_their_probabilities(tmp_path: Path) -> None:
    write_map(tmp_path / "map.png", OccupancyMap(WORLD3, PROB3), mode="scale")
    loaded = load_probability_map(tmp_path / "map.yaml")
    # grey = round(255 (1 - p)): p comes back within half a grey level
    np.testing.assert_allclose(loaded.prob, PROB3, atol=0.5 / 255)
    assert np.isnan(loaded.prob[1, 1]) and loaded.occupied_thresh == 0.65
    # without the pixels (a LoadedMap made by hand) only the loader's occupancy / 100 is known
    full = load_map(tmp_path / "map.yaml")
    np.testing.assert_array_equal(full.stored_probability(), loaded.prob)
    bare = replace(full, pixels=None)
    np.testing.assert_array_equal(bare.stored_probability(), full.probability())


def test_a_map_built_in_memory_scores_as_the_same_map_written_and_loaded(tmp_path: Path) -> None:
    # p on whole grey levels (k / 255), so the scale image stores it exactly; a corner unknown
    rng = np.random.default_rng(7)
    spec = GridSpec(-2.0, -7.0, 1.0, 10, 10)
    prob = rng.integers(0, 256, spec.shape) / 255.0
    prob[:2, :2] = np.nan
    omap = OccupancyMap(spec, prob)
    write_map(tmp_path / "map.png", omap, mode="scale", occupied_thresh=0.6, free_thresh=0.25)
    in_memory = ProbabilityMap.from_occupancy_map(omap, 0.6)
    loaded = load_probability_map(tmp_path / "map.yaml")
    region = np.ones(WORLD10.shape, dtype=bool)
    region[5:, :] = False
    a = evaluate_map(in_memory, WALLS10, WORLD10, region, START)
    b = evaluate_map(loaded, WALLS10, WORLD10, region, START)
    assert a == b and b.occupied_thresh == 0.6 and 0.0 < b.coverage < 1.0
    np.testing.assert_array_equal(a.p_world, b.p_world)


def test_cli_with_a_log_in_the_odometry_frame(tmp_path: Path) -> None:
    world = _write_world(tmp_path, WALLS10, WORLD10)
    rng = np.random.default_rng(5)
    world_prob = np.where(WALLS10, 0.9, 0.1) + rng.uniform(-0.05, 0.05, (10, 10))
    write_map(tmp_path / "global.png", OccupancyMap(WORLD10, world_prob), mode="scale")
    spec = GridSpec(-2.0, -7.0, 1.0, 10, 10)
    rows, cols = np.indices(spec.shape)
    u, v = spec.cell_center(cols, rows)
    wc, wr = WORLD10.world_to_cell(3.0 - v, 2.0 + u)
    write_map(tmp_path / "odom.png", OccupancyMap(spec, world_prob[wr, wc]), mode="scale")
    # the robot stands at START and turns on the spot; odometry starts at 0
    turns = [(3.0, 2.0, math.pi / 2 + k * 0.3) for k in range(25)]
    odo = [(0.0, 0.0, k * 0.3) for k in range(25)]
    save_csv_log(log_with_truth(turns, odo), tmp_path / "run.csv")
    results = []
    for name, frame in (("global", "world"), ("odom", "odometry")):
        code, out, err = run(
            "evaluate", str(tmp_path / f"{name}.yaml"), "--truth", str(world),
            "--log", str(tmp_path / "run.csv"), "--frame", frame, "--json",
        )  # fmt: skip
        assert code == 0, err
        results.append(json.loads(out))
    a, b = results
    assert b["map_to_world"] == pytest.approx([3.0, 2.0, math.pi / 2])
    # the region comes from the log alone: both maps are scored on the same cells
    assert a["cells"] == b["cells"] and 0 < a["cells"] < 100
    assert a["region"] == "sensed from the true path"
    for key in ("nll", "brier", "ece", "precision", "recall", "coverage"):
        assert a[key] == pytest.approx(b[key]), key


def test_cli_plot(tmp_path: Path) -> None:
    world = _write_world(tmp_path, WALLS3, WORLD3)
    write_map(tmp_path / "map.pgm", OccupancyMap(WORLD3, PROB3), mode="raw")
    args = ["evaluate", str(tmp_path / "map.yaml"), "--truth", str(world), "--frame", "world"]
    code, _, err = run(*args, "--plot", str(tmp_path / "eval.png"))
    assert code == 0, err
    assert (tmp_path / "eval.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code, _, err = run(*args, "--plot", str(tmp_path / "eval.png"))
    assert code == 1 and "exists (use --force to overwrite)" in err


def test_map_rgb_draws_one_minus_p_and_unknown_pale_blue() -> None:
    rgb = map_rgb(np.array([[0.25, np.nan], [1.0, 0.0]]))
    assert rgb.shape == (2, 2, 3)
    assert rgb[0, 0].tolist() == [0.75] * 3 and rgb[0, 1].tolist() == list(UNKNOWN_RGB)
    assert rgb[1, 0].tolist() == [0.0] * 3 and rgb[1, 1].tolist() == [1.0] * 3


@pytest.mark.parametrize(
    ("flag", "others"),
    [
        ("--plot", ("--frame", "world")),
        ("--spread-plot", ("--log", str(SAMPLES / "corridor_loop.csv"), "--odometry-error", "o")),
    ],
)
def test_plot_without_matplotlib_is_a_clear_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, flag: str, others: tuple[str, ...]
) -> None:
    world = _write_world(tmp_path, WALLS3, WORLD3)
    write_map(tmp_path / "map.pgm", OccupancyMap(WORLD3, PROB3), mode="raw")
    (tmp_path / "o").write_text("range_m_per_m: 0.01\n")  # present: checked before the plot
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib now fails
    monkeypatch.chdir(tmp_path)
    before = names(tmp_path)
    code, _, err = run(
        "evaluate", str(tmp_path / "map.yaml"), "--truth", str(world), *others,
        flag, str(tmp_path / "eval.png"),
    )  # fmt: skip
    assert code == 1
    assert err == (
        f"Error: {flag} needs matplotlib, an optional extra: pip install 'gridmap-cli[plot]'\n"
    )
    assert names(tmp_path) == before


def test_bad_inputs(tmp_path: Path) -> None:
    world = _write_world(tmp_path, WALLS3, WORLD3)
    write_map(tmp_path / "map.pgm", OccupancyMap(WORLD3, PROB3), mode="raw")
    m = str(tmp_path / "map.yaml")
    code, _, err = run("evaluate", m, "--truth", str(tmp_path / "absent.yaml"), "--frame", "world")
    assert code == 1 and err == f"Error: {tmp_path / 'absent.yaml'}: no such file\n"
    code, _, err = run("evaluate", str(tmp_path / "map.pgm"), "--truth", str(world))
    assert code == 2 and "map.pgm: MAP must be a map's YAML file" in err
    code, _, err = run("evaluate", m, "--truth", str(world))
    assert code == 2 and "a map in the odometry frame needs --log" in err
    (tmp_path / "broken.yaml").write_text("image: nothing.pgm\n")
    broken = str(tmp_path / "broken.yaml")
    code, _, err = run("evaluate", broken, "--truth", str(world), "--frame", "world")
    assert code == 1 and "broken.yaml: missing key 'resolution'" in err
    log = log_with_truth([(1.5, 1.5, 0.0)] * 2, [(0, 0, 0)] * 2)
    plain = RangeLog(log.source, log.poses, log.readings, log.sensor_names, metadata={})
    save_csv_log(plain, tmp_path / "plain.csv")
    code, _, err = run("evaluate", m, "--truth", str(world), "--log", str(tmp_path / "plain.csv"))
    assert code == 1 and "plain.csv: the log has no ground truth" in err


@pytest.mark.skipif(not (SAMPLES / "corridor_loop.csv").exists(), reason="no samples")
def test_the_corridor_sample_mapped_with_truth_scores_better(tmp_path: Path) -> None:
    log = str(SAMPLES / "corridor_loop.csv")
    world = str(SAMPLES / "worlds" / "corridor_loop.yaml")
    scores = {}
    for pose, frame in (("odometry", "odometry"), ("global", "world")):
        out = tmp_path / f"{pose}.png"
        code, _, err = run(
            "build", log, "-o", str(out), "--map-mode", "scale", "--pose", pose, "-q"
        )
        assert code == 0, err
        code, text, err = run(
            "evaluate", str(out.with_suffix(".yaml")), "--truth", world, "--log", log,
            "--frame", frame, "--json",
        )  # fmt: skip
        assert code == 0, err
        scores[pose] = json.loads(text)
    # the drifting odometry bends the walls away from the truth; the true poses do not
    assert scores["odometry"]["cells"] == scores["global"]["cells"]
    assert scores["global"]["nll"] < scores["odometry"]["nll"]
    assert scores["global"]["f1"] > 0.8 > 0.5 > scores["odometry"]["f1"]
    assert scores["global"]["coverage"] > 0.99


def test_a_reference_map_with_unknown_cells_is_scored_on_its_known_cells(tmp_path: Path) -> None:
    """A 3 x 3 reference computed by hand: its unknown cells are not free, they are skipped."""
    from gridmap_cli.evaluation.evaluate import evaluate_map, load_truth

    # rows top to bottom as in the image: 0 occupied (black), 254 free, 205 unknown
    pixels = bytes([205, 254, 0, 254, 254, 205, 0, 254, 205])
    (tmp_path / "ref.pgm").write_bytes(b"P5\n3 3\n255\n" + pixels)
    (tmp_path / "ref.yaml").write_text(
        "image: ref.pgm\nresolution: 1.0\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    truth = load_truth(tmp_path / "ref.yaml")
    # row 0 at the bottom: [occ, free, unknown], [free, free, unknown], [unknown, free, occ]
    assert truth.walls.tolist() == [
        [True, False, False],
        [False, False, False],
        [False, False, True],
    ]
    assert truth.known.tolist() == [[True, True, False], [True, True, False], [False, True, True]]
    spec = truth.spec
    prob = np.array([[0.9, 0.2, 0.7], [0.5, 0.1, 0.3], [0.4, np.nan, 0.6]])
    pmap = ProbabilityMap(spec, prob, 0.65)
    e = evaluate_map(pmap, truth.walls, spec, None, (0.0, 0.0, 0.0), truth.known)
    # the six known cells: occupied 0.9, 0.6; free 0.2, 0.5, 0.1 and one the map does not know
    assert e.cells == 6 and e.occupied_cells == 2
    nll = -(math.log(0.9) + math.log(0.8) + math.log(0.5) + math.log(0.9) + math.log(0.5)
            + math.log(0.6)) / 6  # fmt: skip
    assert e.nll == pytest.approx(nll)
    assert e.brier == pytest.approx((0.01 + 0.04 + 0.25 + 0.01 + 0.25 + 0.16) / 6)
    assert e.coverage == pytest.approx(5 / 6)
    # the unknown cells' p (0.7, 0.3, 0.4) counts nowhere: treated as free they would add cost
    everything = evaluate_map(pmap, truth.walls, spec)
    assert everything.cells == 9 and everything.nll > e.nll
