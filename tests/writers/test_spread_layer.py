"""The pose-spread layer beside an error-aware or slam map: its values, its files, its topic."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader

from gridmap_cli.evaluation.spread_map import spread_layer
from gridmap_cli.mapping.grid import GridSpec
from gridmap_cli.mapping.mapfile import load_map
from gridmap_cli.poses.sync import SensorReadings
from gridmap_cli.poses.uncertainty.pose_uncertainty import PoseUncertainty
from gridmap_cli.robot import RangeSensor
from gridmap_cli.writers.spread_layer import SPREAD_TOPIC, spread_levels
from tests.helpers import names, run

ODOMETRY = "gridmap-odometry-error: 1\nbearing_rad_per_sqrt_rad: 0.05\nrange_m_per_sqrt_m: 0.05\n"


def test_levels_are_two_centimetres_capped_at_two_metres() -> None:
    spread = np.array([[0.0, 0.011, 0.03, 2.5, np.nan]])
    assert spread_levels(spread).tolist() == [[0, 1, 2, 100, -1]]


def test_a_cell_takes_the_mean_spread_of_the_rays_that_crossed_it() -> None:
    """Two laser readings along one row of cells, one taken at spread 0 and one at 0.4 m (the
    covariance grows in time): the cells both crossed hold 0.2, the cells only the longer one
    crossed 0.4; a known cell no ray crossed takes its nearest crossed cell's value, and a cell
    the map does not know stays NaN."""
    spec = GridSpec(0.0, 0.0, 1.0, 6, 2)
    laser = RangeSensor("laser_0", 0.0, 0.0, 0.0, 0.0, 0.1, 10.0, kind="laser")
    readings = SensorReadings(
        stamp_ns=np.array([0, 10], dtype=np.int64),
        sensor=np.zeros(2, np.int32),
        range_m=np.array([2.0, 4.0]),
        x_m=np.full(2, 0.5),
        y_m=np.full(2, 0.5),
        theta_rad=np.zeros(2),
        sensors=(laser,),
    )
    cov = np.zeros((2, 3, 3))
    cov[1, 0, 0] = cov[1, 1, 1] = 0.4**2
    uncertainty = PoseUncertainty(np.array([0, 10], dtype=np.int64), np.zeros(2), np.zeros(2), cov)
    known = np.zeros(spec.shape, dtype=bool)
    known[0, :5] = True
    known[1, 0] = True
    layer = spread_layer(spec, iter([readings]), uncertainty, known)
    np.testing.assert_allclose(layer[0, :5], [0.2, 0.2, 0.2, 0.4, 0.4])
    assert layer[1, 0] == 0.2  # known, not crossed: the cell below it
    assert np.isnan(layer[0, 5]) and np.isnan(layer[1, 1:]).all()


def test_an_error_aware_build_writes_the_layer_beside_the_map(
    tmp_path: Path, room_csv: Path
) -> None:
    cal = tmp_path / "odo.yaml"
    cal.write_text(ODOMETRY)
    out = tmp_path / "out"
    out.mkdir()
    code, stdout, stderr = run("build", str(room_csv), "-o", str(out / "m.png"), "--mode",
                               "error-aware", "--odometry-error", str(cal), "--json",
                               "--map-mode", "scale")  # fmt: skip
    assert code == 0, stderr
    assert names(out) == {"m.png", "m.yaml", "m_spread.png", "m_spread.yaml"}
    summary = json.loads(stdout)
    assert summary["spread"] == str(out / "m_spread.yaml")
    spread = summary["quality"]["spread"]
    assert spread["known_cells"] > 0 and spread["share_within_m"]["1"] == 1.0
    assert "pose spread of the known cells" in stderr
    text = (out / "m_spread.yaml").read_text()
    assert "0.02 m of position spread" in text.splitlines()[0]
    assert yaml.safe_load(text)["mode"] == "raw"
    layer, image = load_map(out / "m_spread.yaml"), load_map(out / "m.yaml")
    assert layer.spec == image.spec
    # the layer knows the cells the map knows, and a map_server loader reads them as levels
    assert (np.isnan(layer.stored_probability()) == np.isnan(image.stored_probability())).all()


def test_an_existing_layer_stops_the_build_before_anything_is_written(
    tmp_path: Path, room_csv: Path
) -> None:
    cal = tmp_path / "odo.yaml"
    cal.write_text(ODOMETRY)
    (tmp_path / "m_spread.yaml").write_text("keep")
    code, _, stderr = run("build", str(room_csv), "-o", str(tmp_path / "m.png"), "--mode",
                          "error-aware", "--odometry-error", str(cal))  # fmt: skip
    assert code == 1
    last = stderr.strip().splitlines()[-1]
    assert last.endswith("m_spread.yaml exists (use --force to overwrite)")
    assert names(tmp_path) == {"room.csv", "odo.yaml", "m_spread.yaml"}
    assert (tmp_path / "m_spread.yaml").read_text() == "keep"


def test_a_standard_map_has_no_layer(tmp_path: Path, room_csv: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    code, _, stderr = run("build", str(room_csv), "-o", str(out / "m.png"))
    assert code == 0, stderr
    assert names(out) == {"m.png", "m.yaml"}
    assert "pose spread" not in stderr


def test_an_mcap_map_carries_the_layer_on_its_own_topic(tmp_path: Path, room_csv: Path) -> None:
    cal = tmp_path / "odo.yaml"
    cal.write_text(ODOMETRY)
    out = tmp_path / "m.mcap"
    code, _, stderr = run("build", str(room_csv), "-o", str(out), "--mode", "error-aware",
                          "--odometry-error", str(cal))  # fmt: skip
    assert code == 0, stderr
    with out.open("rb") as handle:
        topics = [channel.topic for _, channel, _ in make_reader(handle).iter_messages()]
    assert topics == ["/map", SPREAD_TOPIC]
    plain = tmp_path / "plain.mcap"
    code, _, stderr = run("build", str(room_csv), "-o", str(plain))
    assert code == 0, stderr
    with plain.open("rb") as handle:
        assert [c.topic for _, c, _ in make_reader(handle).iter_messages()] == ["/map"]


def test_a_failed_layer_write_leaves_neither_the_map_nor_the_layer(
    tmp_path: Path, room_csv: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import gridmap_cli.writers.spread_layer as layer_module

    def full(_: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(layer_module, "spread_pixels", full)
    cal = tmp_path / "odo.yaml"
    cal.write_text(ODOMETRY)
    code, _, stderr = run("build", str(room_csv), "-o", str(tmp_path / "m.png"), "--mode",
                          "error-aware", "--odometry-error", str(cal))  # fmt: skip
    assert code == 1
    assert "cannot write the map: No space left on device" in stderr.strip().splitlines()[-1]
    assert names(tmp_path) == {"room.csv", "odo.yaml"}  # no map, no layer, no temporary file


def test_a_layer_path_that_is_a_folder_is_refused_before_reading(
    tmp_path: Path, room_csv: Path
) -> None:
    cal = tmp_path / "odo.yaml"
    cal.write_text(ODOMETRY)
    (tmp_path / "m_spread.png").mkdir()
    code, _, stderr = run("build", str(room_csv), "-o", str(tmp_path / "m.png"), "--mode",
                          "error-aware", "--odometry-error", str(cal), "--force")  # fmt: skip
    assert code == 2 and "m_spread.png is a directory" in stderr
    assert names(tmp_path) == {"room.csv", "odo.yaml", "m_spread.png"}
