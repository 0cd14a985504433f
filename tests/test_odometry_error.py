"""The odometry-error model: f and g by hand, travelled distance and rotation, the YAML file."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from gridmap_cli.errors import InputFileError
from gridmap_cli.poses.odometry_error import (
    OdometryError,
    correct_track,
    load_odometry_error,
    odometry_error_yaml,
    save_odometry_error,
    travelled,
    travelled_at,
)
from gridmap_cli.records import PoseTrack
from gridmap_cli.sim.odometry import OdometryErrorModel
from gridmap_cli.yamlfile import format_float, number

MODEL = OdometryError(
    range_m_per_m=0.02,
    range_m_per_sqrt_m=0.01,
    bearing_rad_per_rad=0.03,
    bearing_rad_per_sqrt_rad=0.02,
    heading_drift_rad_per_m=0.005,
    sonar_relative_error=0.01,
)


def test_f_and_g_by_hand() -> None:
    # f(4) = 0.02 * 4 + 0.01 * 2 = 0.10; g(4, 1) = 0.03 + 0.02 + 0.005 * 4 = 0.07
    assert MODEL.f(4.0) == pytest.approx(0.10)
    assert MODEL.g(4.0, 1.0) == pytest.approx(0.07)
    np.testing.assert_allclose(MODEL.f([0.0, 1.0, 9.0]), [0.0, 0.03, 0.21])
    assert MODEL.g(np.zeros((2, 3)), 0.0).shape == (2, 3)
    # eq. 11 and 12: sigma_z = k z + f, sigma_theta = beta / 2 + g
    assert MODEL.sigma_range(3.0, 4.0) == pytest.approx(0.03 + 0.10)
    assert MODEL.sigma_bearing(math.radians(25), 4.0, 1.0) == pytest.approx(
        math.radians(12.5) + 0.07
    )


def test_spreads_never_shrink_with_travel() -> None:
    d = np.linspace(0.0, 100.0, 101)
    assert np.all(np.diff(MODEL.f(d)) > 0)
    assert np.all(np.diff(MODEL.g(d, d / 10)) > 0)


def test_the_default_model_is_the_sonar_alone() -> None:
    m = OdometryError()
    assert m.sonar_relative_error == 0.01
    assert m.f(100.0) == 0.0 and m.g(100.0, 30.0) == 0.0


@pytest.mark.parametrize("bad", [-0.1, math.inf, math.nan])
def test_coefficients_must_be_finite_and_non_negative(bad: float) -> None:
    with pytest.raises(ValueError, match="range_m_per_m must be a finite number >= 0"):
        OdometryError(range_m_per_m=bad)


def test_travelled_sums_steps_and_absolute_turns() -> None:
    # 1 m east, turn +90 deg in place, 2 m north, turn -90 deg (across no wrap), 0.5 m east;
    # then a turn from 179 deg to -179 deg is 2 deg, not 358
    xs = [0, 1, 1, 1, 1, 1.5, 1.5]
    ys = [0, 0, 0, 2, 2, 2, 2]
    ths = [0, 0, 90, 90, 0, 0, 0]
    rows = [(x, y, math.radians(t)) for x, y, t in zip(xs, ys, ths, strict=True)]
    track = PoseTrack.from_rows(np.arange(7, dtype=np.int64), rows)
    d, r = travelled(track)
    np.testing.assert_allclose(d, [0, 1, 1, 3, 3, 3.5, 3.5])
    np.testing.assert_allclose(r, np.radians([0, 0, 90, 90, 180, 180, 180]))
    wrap = PoseTrack.from_rows(
        np.arange(2, dtype=np.int64), [(0, 0, math.radians(179)), (0, 0, math.radians(-179))]
    )
    assert travelled(wrap)[1][-1] == pytest.approx(math.radians(2))
    d_at, r_at = travelled_at(track, np.asarray([0, 1, 2], dtype=np.int64))
    np.testing.assert_allclose(d_at, [0, 1, 1])
    np.testing.assert_allclose(r_at, [0, 0, math.pi / 2])
    half = travelled_at(track, np.asarray([-5, 99], dtype=np.int64))
    np.testing.assert_allclose(half[0], [0.0, 3.5])


@given(st.lists(st.floats(-math.pi + 0.01, math.pi - 0.01), min_size=1, max_size=20))
def test_rotation_is_the_sum_of_absolute_increments(turns: list[float]) -> None:
    theta = np.concatenate([[0.0], np.cumsum(turns)])
    track = PoseTrack(
        stamp_ns=np.arange(theta.shape[0], dtype=np.int64),
        x_m=np.zeros_like(theta),
        y_m=np.zeros_like(theta),
        theta_rad=(theta + math.pi) % (2 * math.pi) - math.pi,
    )
    assert travelled(track)[1][-1] == pytest.approx(float(np.sum(np.abs(turns))), abs=1e-9)


def test_yaml_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "odo.yaml"
    tiny = OdometryError(heading_drift_rad_per_m=1e-5, range_m_per_m=0.1 + 0.2)
    save_odometry_error(tiny, path, comments=["from a test"])
    text = path.read_text()
    assert text.startswith("# from a test\ngridmap-odometry-error: 1\n")
    assert "heading_drift_rad_per_m: 1.0e-05" in text  # PyYAML reads '1e-05' as a string
    assert load_odometry_error(path) == tiny
    assert [p.name for p in tmp_path.iterdir()] == ["odo.yaml"]


@given(st.floats(allow_nan=False, allow_infinity=False))
def test_yaml_floats_read_back_exactly_as_floats(value: float) -> None:
    # what the map YAML and the odometry-error file write, PyYAML loads as the same float
    loaded = yaml.safe_load(f"x: {format_float(value)}")["x"]
    assert isinstance(loaded, float) and loaded == value
    assert number(loaded) == value


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_yaml_floats_must_be_finite(bad: float) -> None:
    with pytest.raises(ValueError, match="non-finite"):
        format_float(bad)


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        (3, 3.0),
        (0.5, 0.5),
        ("5e-2", 0.05),
        (" 1e-3 ", 0.001),
        (True, None),
        ("x", None),
        (None, None),
    ],
)
def test_yaml_numbers_include_exponents_without_a_point(value: object, expected: object) -> None:
    # PyYAML reads '5e-2' as a string; yaml-cpp (and so ROS) reads it as a number
    assert number(value) == expected


def test_version_2_adds_keys_and_is_written_only_when_they_are_used(tmp_path: Path) -> None:
    path = tmp_path / "odo.yaml"
    path.write_text("gridmap-odometry-error: 2\nlateral_m_per_sqrt_m: 0.01\n")
    model = load_odometry_error(path)
    assert model == OdometryError(lateral_m_per_sqrt_m=0.01)
    assert odometry_error_yaml(model).splitlines()[0] == "gridmap-odometry-error: 2"
    plain = odometry_error_yaml(OdometryError(range_m_per_m=0.02))
    assert plain.splitlines()[0] == "gridmap-odometry-error: 1"
    assert "lateral" not in plain


def test_version_3_holds_signed_biases_and_is_written_only_when_they_are_used(
    tmp_path: Path,
) -> None:
    path = tmp_path / "odo.yaml"
    path.write_text("gridmap-odometry-error: 3\ndistance_scale_bias: -0.02\n")
    model = load_odometry_error(path)
    assert model == OdometryError(distance_scale_bias=-0.02) and model.has_bias
    text = odometry_error_yaml(model)
    assert text.splitlines()[0] == "gridmap-odometry-error: 3"
    path.write_text(text)
    assert load_odometry_error(path) == model
    assert not OdometryError(lateral_m_per_sqrt_m=0.01).has_bias
    random = OdometryError(range_m_per_m=0.1, range_m_per_sqrt_m=0.2, turn_scale_bias=0.1)
    assert random.random_part() == OdometryError(range_m_per_sqrt_m=0.2)


def test_correct_track_undoes_known_scale_turn_and_drift() -> None:
    # a true arc-and-turn path; odometry made from it with exact systematic errors
    n = 2000
    true_step, true_turn = 0.05, np.where(np.arange(n) % 100 < 80, 0.0, math.radians(4.5))
    bias = OdometryError(
        distance_scale_bias=0.03, turn_scale_bias=-0.04, heading_drift_bias_rad_per_m=0.01
    )

    def integrate(step: float, turn: np.ndarray) -> PoseTrack:
        th = np.concatenate([[0.3], 0.3 + np.cumsum(turn)])
        x = np.concatenate([[1.0], 1.0 + np.cumsum(step * np.cos(th[:-1]))])
        y = np.concatenate([[2.0], 2.0 + np.cumsum(step * np.sin(th[:-1]))])
        return PoseTrack(np.arange(n + 1, dtype=np.int64) * 10**8, x, y, th)

    truth = integrate(true_step, true_turn)
    odometry = integrate(true_step * 1.03, true_turn * 0.96 + 0.01 * true_step * 1.0)
    fixed = correct_track(odometry, bias)
    error = np.hypot(fixed.x_m - truth.x_m, fixed.y_m - truth.y_m)
    before = np.hypot(odometry.x_m - truth.x_m, odometry.y_m - truth.y_m)
    assert before.max() > 0.5 and error.max() < 0.01 * before.max()
    assert fixed.x_m[0] == odometry.x_m[0] and fixed.theta_rad[0] == odometry.theta_rad[0]
    assert correct_track(odometry, OdometryError(range_m_per_m=0.5)) is odometry


def test_missing_keys_take_their_defaults(tmp_path: Path) -> None:
    path = tmp_path / "odo.yaml"
    path.write_text("gridmap-odometry-error: 1\nrange_m_per_m: 0.02\nbearing_rad_per_rad: 3e-2\n")
    assert load_odometry_error(path) == OdometryError(range_m_per_m=0.02, bearing_rad_per_rad=0.03)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("range_m_per_m: 0.02\n", "odo.yaml: missing 'gridmap-odometry-error: 1'"),
        ("gridmap-odometry-error: 4\n", "odo.yaml:1: unsupported gridmap-odometry-error version 4"),
        (
            "gridmap-odometry-error: 2\nturn_scale_bias: 0.01\n",
            "odo.yaml:2: unknown key 'turn_scale_bias' in version 2",
        ),
        (
            "gridmap-odometry-error: 3\ndistance_scale_bias: -0.7\n",
            "odo.yaml:2: distance_scale_bias must be a finite number between -0.5 and 0.5",
        ),
        (
            "gridmap-odometry-error: 1\nrange_per_m: 0.02\n",
            "odo.yaml:2: unknown key 'range_per_m' in version 1 (known: range_m_per_m,",
        ),
        (
            "gridmap-odometry-error: 1\nlateral_m_per_sqrt_m: 0.02\n",
            "odo.yaml:2: unknown key 'lateral_m_per_sqrt_m' in version 1 (known:",
        ),
        (
            "gridmap-odometry-error: 1\n\nrange_m_per_m: -0.02\n",
            "odo.yaml:3: range_m_per_m must be a finite number >= 0, got -0.02",
        ),
        (
            "gridmap-odometry-error: 1\nbearing_rad_per_rad: .nan\n",
            "odo.yaml:2: bearing_rad_per_rad must be a finite number >= 0",
        ),
        (
            "gridmap-odometry-error: 1\nsonar_relative_error: .inf\n",
            "odo.yaml:2: sonar_relative_error must be a finite number >= 0",
        ),
        (
            "gridmap-odometry-error: 1\nsonar_relative_error: one percent\n",
            "odo.yaml:2: sonar_relative_error must be a number, got 'one percent'",
        ),
        ("gridmap-odometry-error: 1\nrange_m_per_m: [1\n", "odo.yaml:3: not valid YAML"),
        ("- 1\n- 2\n", "odo.yaml: expected a mapping"),
    ],
)
def test_bad_files_name_file_and_line(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "odo.yaml"
    path.write_text(text)
    with pytest.raises(InputFileError) as info:
        load_odometry_error(path)
    assert str(info.value).startswith(str(tmp_path / message))


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="no such file"):
        load_odometry_error(tmp_path / "absent.yaml")


def test_yaml_text_is_what_the_docs_show() -> None:
    assert odometry_error_yaml(OdometryError()) == (
        "gridmap-odometry-error: 1\n"
        "range_m_per_m: 0.0\n"
        "range_m_per_sqrt_m: 0.0\n"
        "bearing_rad_per_rad: 0.0\n"
        "bearing_rad_per_sqrt_rad: 0.0\n"
        "heading_drift_rad_per_m: 0.0\n"
        "sonar_relative_error: 0.01\n"
    )


def test_the_simulators_errors_as_coefficients() -> None:
    sim = OdometryErrorModel(
        scale_error=-0.01,
        turn_scale_error=0.02,
        heading_drift_rad_per_m=-0.003,
        sigma_dist_per_sqrt_m=0.04,
        sigma_turn_per_sqrt_rad=0.05,
    )
    assert sim.as_odometry_error() == OdometryError(
        range_m_per_m=0.01,  # systematic terms as magnitudes: a spread has no sign
        range_m_per_sqrt_m=0.04,
        bearing_rad_per_rad=0.02,
        bearing_rad_per_sqrt_rad=0.05,
        heading_drift_rad_per_m=0.003,
        sonar_relative_error=0.01,
    )
    # drift 1 (the defaults), and every simulator term feeds exactly one coefficient
    drift1 = OdometryErrorModel().as_odometry_error().as_dict()
    assert drift1 == {
        "range_m_per_m": 0.01,
        "range_m_per_sqrt_m": 0.01,
        "bearing_rad_per_rad": 0.02,
        "bearing_rad_per_sqrt_rad": 0.02,
        "heading_drift_rad_per_m": math.radians(0.2),
        "sonar_relative_error": 0.01,
        "lateral_m_per_sqrt_m": 0.0,
        "heading_rad_per_sqrt_m": 0.0,
        "distance_scale_bias": 0.0,
        "turn_scale_bias": 0.0,
        "heading_drift_bias_rad_per_m": 0.0,
    }
    for f in dataclasses.fields(OdometryErrorModel):
        one = dataclasses.replace(OdometryErrorModel().scaled(0.0), **{f.name: 0.5})
        coefficients = one.as_odometry_error().as_dict()
        assert sorted(coefficients.values()) == [0.0] * 9 + [0.01, 0.5], f.name


def test_travelled_at_with_the_sums_made_once_gives_the_same_bits() -> None:
    rng = np.random.default_rng(3)
    n = 2000
    stamps = np.cumsum(rng.integers(1, 10**8, n)).astype(np.int64)
    track = PoseTrack(stamps, rng.normal(size=n), rng.normal(size=n), rng.uniform(-3, 3, n))
    sums = travelled(track)
    for lo, hi in ((-5 * 10**8, stamps[40]), (stamps[10], stamps[200]), (stamps[300], 10**12)):
        exact = stamps[(stamps >= lo) & (stamps <= hi)]  # readings at a pose's own stamp too
        q = np.sort(np.concatenate((rng.integers(lo, hi, 500), exact))).astype(np.int64)
        whole = travelled_at(track, q)
        part = travelled_at(track, q, sums)
        assert all(a.tobytes() == b.tobytes() for a, b in zip(whole, part, strict=True))
