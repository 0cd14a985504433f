from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from gridmap_cli.errors import RobotDescriptionError, UnknownRobotError
from gridmap_cli.robot import load_robot, parse_robot_yaml, preset_names

ARIA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "aria"


def test_presets_are_listed() -> None:
    assert {"p3at", "p3dx"} <= set(preset_names())


@pytest.mark.parametrize("robot", ["p3at", "p3dx"])
def test_presets_match_the_real_aria_parameter_files(robot: str) -> None:
    path = ARIA / f"{robot}.p"
    if not path.is_file():
        pytest.skip("../shared/data/aria is not present")
    text = path.read_text()
    units = re.findall(r"^SonarUnit\s+(\d+)\s+(-?\d+)\s+(-?\d+)\s+(-?\d+)", text, re.M)
    max_mm = int(re.search(r"^SonarMaxRange\s+(\d+)", text, re.M).group(1))
    desc = load_robot(robot)
    assert len(desc.sensors) == len(units) == 16
    for sensor, (n, x, y, heading) in zip(desc.sensors, units, strict=True):
        assert sensor.name == f"sonar{n}"
        assert sensor.x_m == pytest.approx(int(x) / 1000, abs=1e-12)
        assert sensor.y_m == pytest.approx(int(y) / 1000, abs=1e-12)
        assert sensor.yaw_rad == pytest.approx(math.radians(int(heading)), abs=1e-12)
        assert sensor.max_range_m == pytest.approx(max_mm / 1000)


def test_robot_yaml_file(tmp_path: Path) -> None:
    path = tmp_path / "bot.yaml"
    path.write_text(
        "gridmap-robot: 1\nname: bot\ndefaults: {beam_width_deg: 30, max_range_m: 5}\n"
        "sensors:\n  - {name: front, x_m: 0.2, y_m: 0, yaw_deg: 0}\n"
        "  - {name: left, x_m: 0, y_m: 0.1, yaw_deg: 90, max_range_m: 3}\n"
    )
    robot = load_robot(str(path))
    assert robot.names() == ("front", "left")
    assert robot.sensors[1].max_range_m == 3.0 and robot.sensors[0].max_range_m == 5.0
    assert robot.sensors[1].yaw_rad == pytest.approx(math.pi / 2)
    assert robot.sensors[0].beam_width_rad == pytest.approx(math.radians(30))


def test_unknown_robot_names_presets() -> None:
    with pytest.raises(UnknownRobotError) as info:
        load_robot("r2d2")
    assert str(info.value) == (
        f"unknown robot 'r2d2': not a preset ({', '.join(preset_names())}) and no such file"
    )
    assert {"p3at", "p3dx", "p3at-lms200"} <= set(preset_names())


BASE = "gridmap-robot: 1\nname: bot\nsensors:\n"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("name: bot\nsensors: []\n", "missing 'gridmap-robot: 1'"),
        ("gridmap-robot: 1\nname: bot\nsensors: []\n", "'sensors' must be a non-empty list"),
        (
            BASE + "  - {name: a, x_m: 0, y_m: 0, yaw_deg: 0, beam_width_deg: 25}\n",
            "bot.yaml:4: sensor 0: missing keys ['max_range_m']",
        ),
        (
            BASE + "  - {name: a, x_m: 0, y_m: 0, yaw_deg: 0, beam_width_deg: 25, max_range_m: 5}\n"
            "  - {name: b, x_m: zero, y_m: 0, yaw_deg: 0, beam_width_deg: 25, max_range_m: 5}\n",
            "bot.yaml:5: sensor 'b' x_m must be a number, got 'zero'",
        ),
        (
            BASE + "  - {name: a, x_m: 0, y_m: 0, yaw_deg: 0, beam_width_deg: 25, max_range_m: 5}\n"
            "  - {name: a, x_m: 0, y_m: 0, yaw_deg: 0, beam_width_deg: 25, max_range_m: 5}\n",
            "duplicate sensor names ['a']",
        ),
        (
            BASE
            + "  - {name: a, x_m: 0, y_m: 0, yaw_deg: 0, beam_width_deg: 200, max_range_m: 5}\n",
            "beam_width_deg must be in [0, 180)",
        ),
        (
            BASE + "  - {name: a, x_m: 0, y_m: 0, yaw_deg: 0, beam_width_deg: 25, max_range_m: 5,"
            " colour: red}\n",
            "unknown keys ['colour']",
        ),
        (BASE + "  - [unclosed\n", "not valid YAML"),
    ],
)
def test_bad_robot_files(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bot.yaml"
    path.write_text(text)
    with pytest.raises(RobotDescriptionError) as info:
        load_robot(str(path))
    assert message in str(info.value)
    assert str(info.value).startswith(str(path))


def test_parse_from_text() -> None:
    robot = parse_robot_yaml(
        BASE + "  - {name: a, x_m: 0, y_m: 0, yaw_deg: 0, beam_width_deg: 25, max_range_m: 5}\n",
        "inline",
    )
    assert robot.name == "bot" and robot.sensors[0].min_range_m == 0.0


def test_a_laser_entry_expands_into_its_beams(tmp_path: Path) -> None:
    path = tmp_path / "bot.yaml"
    path.write_text(
        "gridmap-robot: 1\nname: bot\nsensors:\n"
        "  - {name: scan, kind: laser, x_m: 0.1, y_m: 0.0, yaw_deg: 10, first_deg: -45,"
        " last_deg: 45, samples: 3, max_range_m: 8}\n"
    )
    robot = load_robot(str(path))
    assert robot.names() == ("scan_0", "scan_1", "scan_2")
    assert [s.yaw_rad for s in robot.sensors] == pytest.approx(
        [math.radians(-35), math.radians(10), math.radians(55)]
    )
    assert all(s.kind == "laser" and s.beam_width_rad == 0.0 for s in robot.sensors)


def test_a_laser_entry_upside_down_mirrors_its_beams(tmp_path: Path) -> None:
    """Hung under a deck, the laser's beams sweep from its right: each beam where the upright
    laser's mirror image about its axis points."""
    path = tmp_path / "bot.yaml"
    path.write_text(
        "gridmap-robot: 1\nname: bot\nsensors:\n"
        "  - {name: scan, kind: laser, x_m: 0.1, y_m: 0.0, yaw_deg: 10, first_deg: -45,"
        " last_deg: 45, samples: 3, max_range_m: 8, upside_down: true}\n"
        "  - {name: bare, kind: laser, x_m: 0.2, y_m: 0.0, yaw_deg: 0, upside_down: true}\n"
    )
    robot = load_robot(str(path))
    assert [s.yaw_rad for s in robot.sensors] == pytest.approx(
        [math.radians(55), math.radians(10), math.radians(-35)]
    )
    assert robot.mounts[0].upside_down and robot.mounts[0].name == "bare"


def test_the_lms200_preset_is_the_p3at_plus_its_laser() -> None:
    both = load_robot("p3at-lms200")
    assert both.sensors[:16] == load_robot("p3at").sensors
    lasers = both.sensors[16:]
    assert len(lasers) == 181 and lasers[90].yaw_rad == 0.0 and lasers[0].x_m == 0.16


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ("{name: l, kind: laser, x_m: 0, y_m: 0, yaw_deg: 0, max_range_m: 8}",
         "missing keys ['first_deg', 'last_deg', 'samples']"),
        ("{name: l, kind: laser, x_m: 0, y_m: 0, yaw_deg: 0, first_deg: -90, last_deg: 90,"
         " samples: 2.5, max_range_m: 8}", "samples must be a whole number >= 1, got 2.5"),
        ("{name: s, x_m: 0, y_m: 0, yaw_deg: 0, beam_width_deg: 25, samples: 3,"
         " max_range_m: 4}", "['samples'] only apply to kind: laser"),
        ("{name: s, kind: radar, x_m: 0, y_m: 0, yaw_deg: 0, beam_width_deg: 25,"
         " max_range_m: 4}", "kind must be one of ('sonar', 'laser'), got 'radar'"),
        ("{name: l, kind: laser, x_m: 0, y_m: 0, yaw_deg: 0, upside_down: yes please}",
         "sensor 'l': upside_down must be true or false, got 'yes please'"),
        ("{name: s, x_m: 0, y_m: 0, yaw_deg: 0, beam_width_deg: 25, upside_down: true,"
         " max_range_m: 4}", "['upside_down'] only apply to kind: laser"),
    ],
)  # fmt: skip
def test_bad_laser_entries(tmp_path: Path, entry: str, message: str) -> None:
    path = tmp_path / "bot.yaml"
    path.write_text(f"gridmap-robot: 1\nname: bot\nsensors:\n  - {entry}\n")
    with pytest.raises(RobotDescriptionError) as info:
        load_robot(str(path))
    assert str(info.value).startswith(f"{path}:4: ")
    assert message in str(info.value)
