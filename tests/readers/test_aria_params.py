"""ARIA robot parameter files (``.p``): the real shipped files, malformed ones, and ``--robot``."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
from click.testing import CliRunner

from gridmap_cli.cli import cli
from gridmap_cli.errors import RobotDescriptionError
from gridmap_cli.robot import load_robot
from gridmap_cli.robot.aria_params import (
    AriaLaser,
    parse_aria_params,
    read_aria_params,
)

# tests/readers/ -> /work/main -> /work -> /work/shared/data/aria
ARIA = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "aria"


def real(robot: str) -> Path:
    path = ARIA / f"{robot}.p"
    if not path.is_file():
        pytest.skip("../shared/data/aria is not present")
    return path


# --- the real files ---------------------------------------------------------------------------


@pytest.mark.parametrize("robot", ["p3at", "p3dx"])
def test_real_file_gives_the_preset_field_by_field(robot: str) -> None:
    params = read_aria_params(real(robot))
    assert params.name == robot
    assert params.sonar_max_range_m == 4.335 and params.range_conv_factor == 1.0
    got, preset = params.robot(), load_robot(robot)
    assert got.name == preset.name
    assert len(got.sensors) == len(preset.sensors) == 16
    for mine, theirs in zip(got.sensors, preset.sensors, strict=True):
        assert dataclasses.asdict(mine) == dataclasses.asdict(theirs)
    assert got == preset


def test_real_p3at_lasers() -> None:
    params = read_aria_params(real("p3at"))
    # "Laser 2 parameters" has LaserAutoConnect false and an empty LaserType: not fitted
    assert params.lasers == (
        AriaLaser(
            section="Laser parameters",
            x_m=0.16,
            y_m=0.0,
            yaw_rad=0.0,
            max_range_m=None,
            laser_type="lms2xx",
            auto_connect=True,
        ),
    )


def test_real_p3dx_laser_position() -> None:
    (laser,) = read_aria_params(real("p3dx")).lasers
    assert laser.x_m == pytest.approx(0.018) and laser.laser_type == "lms2xx"


@pytest.mark.parametrize("robot", ["p3at", "p3dx"])
def test_load_robot_reads_a_p_path(robot: str) -> None:
    assert load_robot(str(real(robot))) == load_robot(robot)


# --- syntax details, inline -------------------------------------------------------------------

RING = "".join(
    f"SonarUnit {n} {x} {y} {h}\n"
    for n, x, y, h in [(0, 100, 50, 90), (1, 120, 0, 0), (2, 100, -50, -90)]
)


def test_syntax_keys_case_comments_wrapped_lines_and_mtx_fields() -> None:
    text = (
        "ConfigVersion 2.0\n"
        ";SectionFlags for : \n"
        "Section Sonar parameters\n"
        "sonarnum 3   ; keys are case-insensitive\n"
        ";  SonarUnit <sonarNumber> <x position, mm> <y position, mm> <heading of disc,\n"
        " degrees> <MTX sonar board> <MTX sonar board unit position>\n"
        "SONARUNIT 2 100 -50 -90 1 3 10 25 4335 true\n"
        "SonarUnit 0 100 50 90\n"
        "SonarUnit 1 120 0 0 ; front\n"
        "Section SonarBoard_1\n"
        "SonarMaxRange 3000 ; range [0, 4335]\n"
        "Section Conversion factors\n"
        "RangeConvFactor 0.268\n"
        "Section Laser parameters\n"
        "LaserAutoConnect false\n"
        "LaserType urg2.0\n"
        "LaserX -20\n"
        "LaserTh 180\n"
        "LaserMaxRange 5600\n"
        "Section Laser 2 parameters\n"
        "LaserAutoConnect false\n"
        "LaserType                ; Type of laser.\n"
        "SomethingNew 42 ; unknown keys are ignored\n"
    )
    params = parse_aria_params(text, "/robots/mine.p")
    assert params.name == "mine"  # no Subclass: the file's stem
    assert [u[0] for u in params.sonar_units] == [0, 1, 2]
    assert params.sonar_units[2] == (2, 0.1, -0.05, math.radians(-90))
    assert params.sonar_max_range_m == 3.0 and params.range_conv_factor == 0.268
    (laser,) = params.lasers
    assert laser.section == "Laser parameters" and laser.laser_type == "urg2.0"
    assert not laser.auto_connect and laser.max_range_m == 5.6
    assert laser.x_m == -0.02 and laser.yaw_rad == pytest.approx(math.pi)
    robot = params.robot(beam_width_deg=30.0, min_range_m=0.1)
    assert robot.names() == ("sonar0", "sonar1", "sonar2")
    assert robot.sensors[0].beam_width_rad == pytest.approx(math.radians(30))
    assert robot.sensors[1].min_range_m == 0.1 and robot.sensors[1].max_range_m == 3.0


def test_defaults_without_sonar_max_range_or_conversion() -> None:
    params = parse_aria_params("Subclass bot\n" + RING, "bot.p")
    assert params.name == "bot"
    assert params.sonar_max_range_m == 4.335 and params.range_conv_factor == 1.0
    assert params.lasers == ()


def test_latin1_bytes_are_read(tmp_path: Path) -> None:
    path = tmp_path / "bot.p"
    path.write_bytes(b"Section Sonar parameters ; r\xe9glages\n" + RING.encode())
    assert len(read_aria_params(path).sonar_units) == 3


# --- malformed files --------------------------------------------------------------------------

BAD = [
    (
        "Section Sonar parameters\nSonarNum 16\n",
        2,
        ["no SonarUnit lines"],
    ),
    (
        "Section Sonar parameters\nSonarNum 16 ; number of sonars\n" + RING,
        2,
        ["SonarNum 16", "3 SonarUnit lines"],
    ),
    (
        "Section Sonar parameters\n" + RING + "SonarUnit 3 100 abc 90\n",
        5,
        ["SonarUnit 3 y_mm", "not a number", "'abc'"],
    ),
    (
        "Section Sonar parameters\n" + RING + "SonarUnit 3 100 50\n",
        5,
        ["SonarUnit needs at least 4 fields", "got 3"],
    ),
    (
        "Section Sonar parameters\n" + RING + "SonarUnit 1 100 50 90\n",
        5,
        ["duplicate SonarUnit 1", "first on line 3"],
    ),
    (
        "Section Sonar parameters\nSonarUnit 0 1 2 3\nSonarUnit 2 1 2 3\n",
        3,
        ["SonarUnit 2", "numbered 0..1", "missing 1"],
    ),
    (
        "Section Sonar parameters\nSonarNum sixteen\n" + RING,
        2,
        ["SonarNum", "'sixteen'"],
    ),
    (
        "Section SonarBoard_1\nSonarMaxRange 4.3m\n" + RING,
        2,
        ["SonarMaxRange", "not a number", "'4.3m'"],
    ),
    (
        "RangeConvFactor nan\n" + RING,
        1,
        ["RangeConvFactor", "not a number", "'nan'"],
    ),
    (
        RING + "Section Laser parameters\nLaserAutoConnect true\nLaserX front\n",
        6,
        ["LaserX", "not a number", "'front'"],
    ),
    (
        RING + "Section Laser parameters\nLaserAutoConnect maybe\n",
        5,
        ["LaserAutoConnect", "true or false", "'maybe'"],
    ),
    (
        "\ngridmap-robot: 1\nname: bot\nsensors: []\n",
        2,
        ["not an ARIA robot parameter file", "no 'Section' headers", "'gridmap-robot: 1'"],
    ),
]


@pytest.mark.parametrize(("text", "line", "words"), BAD)
def test_malformed_files_name_path_and_line(
    tmp_path: Path, text: str, line: int, words: list[str]
) -> None:
    path = tmp_path / "bad.p"
    path.write_text(text)
    with pytest.raises(RobotDescriptionError) as info:
        load_robot(str(path))
    message = str(info.value)
    assert message.startswith(f"{path}:{line}: "), message
    for word in words:
        assert word in message


def test_unreadable_path_is_a_robot_error(tmp_path: Path) -> None:
    with pytest.raises(RobotDescriptionError, match="cannot read"):
        read_aria_params(tmp_path / "missing.p")


# --- the command line -------------------------------------------------------------------------


def still_log(tmp_path: Path) -> Path:
    """A few rows of a robot standing at the origin, its sonars seeing a 1.5 m square room."""
    names = [f"sonar{n}" for n in range(16)]
    rows = ["time,x,y,theta," + ",".join(names)]
    for k in range(5):
        rows.append(f"{k * 0.1:.1f},0,0,0," + ",".join(["1.5"] * 16))
    log = tmp_path / "still.csv"
    log.write_text("\n".join(rows) + "\n")
    return log


def test_cli_build_with_a_p_file(tmp_path: Path) -> None:
    p3at = real("p3at")
    log = still_log(tmp_path)
    out = tmp_path / "out" / "map.png"
    out.parent.mkdir()
    result = CliRunner().invoke(cli, ["build", str(log), "-o", str(out), "--robot", str(p3at)])
    assert result.exit_code == 0, result.output
    assert out.read_bytes().startswith(b"\x89PNG")
    assert {p.name for p in out.parent.iterdir()} == {"map.png", "map.yaml"}


def test_cli_build_with_a_malformed_p_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.p"
    bad.write_text("Section Sonar parameters\nSonarNum 16\n" + RING)
    log = still_log(tmp_path)
    out = tmp_path / "out" / "map.png"
    out.parent.mkdir()
    result = CliRunner().invoke(cli, ["build", str(log), "-o", str(out), "--robot", str(bad)])
    assert result.exit_code == 1
    lines = result.stderr.strip().splitlines()
    assert lines == [f"Error: {bad}:2: SonarNum 16 disagrees with the 3 SonarUnit lines"]
    assert list(out.parent.iterdir()) == []
