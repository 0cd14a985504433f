"""--sensors, --start and --end as a user meets them in build, inspect, calibrate and evaluate."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.conftest import room_log_text
from tests.helpers import names, run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
FORMATS = ("corridor_loop.csv", "corridor_loop.2d", "corridor_loop.mcap", "corridor_loop_ros2.mcap")
APRIL_8_S = 1_744_122_870  # 2025-04-08T14:34:30Z


def build(log: Path, out: Path, *args: str) -> tuple[bytes, str]:
    """Build ``log`` into ``out`` (a PNG): the image's bytes and the YAML without its name."""
    code, _, stderr = run("build", str(log), "-o", str(out), "--quiet", "--force", *args)
    assert code == 0, stderr
    yaml_text = out.with_suffix(".yaml").read_text().replace(out.name, "map.png")
    return out.read_bytes(), yaml_text


def keep_columns(text: str, keep: set[str]) -> str:
    """A CSV log with only the pose columns and the sensor columns in ``keep``."""
    lines = text.splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    header = lines[head].split(",")
    cols = [i for i, h in enumerate(header) if h in ("time", "x", "y", "theta") or h in keep]
    rows = [",".join(line.split(",")[i] for i in cols) for line in lines[head:]]
    return "\n".join(lines[:head] + rows) + "\n"


def keep_rows(text: str, start_s: float, end_s: float) -> str:
    """A CSV log with only the rows stamped from ``start_s`` up to, not including, ``end_s``."""
    lines = text.splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    rows = [line for line in lines[head + 1 :] if start_s <= float(line.split(",")[0]) < end_s]
    return "\n".join([*lines[: head + 1], *rows]) + "\n"


def test_a_filtered_build_is_the_build_of_a_log_with_only_those_sensors(tmp_path: Path) -> None:
    full = room_log_text()
    (tmp_path / "full.csv").write_text(full)
    (tmp_path / "part.csv").write_text(keep_columns(full, {"sonar1", "sonar2", "sonar5"}))
    chosen = build(tmp_path / "full.csv", tmp_path / "a.png", "--sensors", "sonar[12]",
                   "--sensors", "sonar5")  # fmt: skip
    alone = build(tmp_path / "part.csv", tmp_path / "b.png")
    assert chosen == alone
    others = [f"--sensors=!sonar{i}" for i in range(16) if i not in (1, 2, 5)]
    excluded = build(tmp_path / "full.csv", tmp_path / "c.png", *others)
    assert excluded == alone


def test_a_window_is_the_build_of_the_log_cut_by_hand(tmp_path: Path) -> None:
    text = (SAMPLES / "corridor_loop.csv").read_text()
    (tmp_path / "cut.csv").write_text(keep_rows(text, 10.0, 60.0))
    window = build(
        SAMPLES / "corridor_loop.csv", tmp_path / "a.png", "--start", "10", "--end", "60"
    )
    cut = build(tmp_path / "cut.csv", tmp_path / "b.png")
    whole = build(SAMPLES / "corridor_loop.csv", tmp_path / "c.png")
    assert window == cut != whole


def test_every_format_selects_alike(tmp_path: Path) -> None:
    args = ("--sensors", "sonar1*", "--sensors", "!sonar12", "--start", "10", "--end", "60.5")
    maps = [build(SAMPLES / name, tmp_path / f"{i}.png", *args) for i, name in enumerate(FORMATS)]
    assert all(m == maps[0] for m in maps)


def test_iso_times_on_a_clock_stamped_log(tmp_path: Path) -> None:
    lines = room_log_text().splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    for i in range(head + 1, len(lines)):
        t, _, rest = lines[i].partition(",")
        lines[i] = f"{APRIL_8_S + float(t):.1f},{rest}"
    log = tmp_path / "clock.csv"
    log.write_text("\n".join(lines) + "\n")
    by_seconds = build(log, tmp_path / "a.png", "--start", "5", "--end", "12.5")
    by_clock = build(log, tmp_path / "b.png", "--start", "2025-04-08T14:34:35Z",
                     "--end", "2025-04-08T16:34:42.5+02:00")  # fmt: skip
    assert by_seconds == by_clock


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["--sensors", "laser*"],
            "Error: --sensors 'laser*' matches no sensor of {log} (it has sonar0..sonar15)",
        ),
        (
            ["--sensors", "sonar1*", "--sensors", "!sonar1*"],
            "Error: --sensors 'sonar1*' '!sonar1*' leave no sensor of {log} (it has "
            "sonar0..sonar15)",
        ),
        (
            ["--start", "200"],
            "Error: {log}: no range readings from 200.000 s to the end (--start 200); the log "
            "spans 0.000 s to 146.700 s (146.7 s)",
        ),
        (
            ["--start", "20", "--end", "10"],
            "Error: --start 20 is not before --end 10: the window would be empty",
        ),
        (
            ["--start", "2025-04-08T14:34:30Z"],
            "Error: --start 2025-04-08T14:34:30Z: {log} is not stamped with clock times (it spans "
            "0.000 s to 146.700 s (146.7 s)); give seconds from its start",
        ),
        (["--end", "later"], "Error: --end 'later': expected seconds from the log's start"),
    ],
)
def test_bad_selections_are_usage_errors_and_write_nothing(
    tmp_path: Path, args: list[str], message: str
) -> None:
    log = SAMPLES / "corridor_loop.csv"
    code, _, stderr = run("build", str(log), "-o", str(tmp_path / "m.png"), *args)
    assert code == 2
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(message.format(log=log)), stderr
    assert names(tmp_path) == set()


def test_the_window_order_is_checked_before_reading(tmp_path: Path) -> None:
    code, _, stderr = run("build", str(tmp_path / "none.csv"), "-o", str(tmp_path / "m.png"),
                          "--start", "3", "--end", "1.5")  # fmt: skip
    assert code == 2 and "--start 3 is not before --end 1.5" in stderr


def with_battery(text: str) -> str:
    lines = text.splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    lines[head] += ",battery_v"
    for i in range(head + 1, len(lines)):
        lines[i] += ",12.6"
    return "\n".join(lines) + "\n"


def test_a_column_that_is_no_sensor_is_ignored_with_one_warning(tmp_path: Path) -> None:
    text = room_log_text()
    log = tmp_path / "run.csv"
    log.write_text(with_battery(text))
    (tmp_path / "plain.csv").write_text(text)
    out = tmp_path / "run.png"
    code, _, stderr = run("build", str(log), "-o", str(out))
    assert code == 0, stderr
    warning = f"Warning: {log}: column 'battery_v' is not a range sensor of robot 'p3dx'; ignored"
    assert stderr.splitlines()[0] == warning and stderr.count("Warning") == 1
    assert "3,200 of 3,200 readings mapped" in stderr  # the voltages are not counted as readings
    plain = build(tmp_path / "plain.csv", tmp_path / "plain.png")
    assert out.read_bytes() == plain[0]
    code, _, stderr = run("build", str(log), "-o", str(out), "--force", "--quiet")
    assert code == 0 and stderr == ""
    code, _, stderr = run("build", str(log), "-o", str(out), "--force", "--sensors", "!battery_v")
    assert code == 0 and "Warning" not in stderr


def test_inspect_describes_the_selection(tmp_path: Path) -> None:
    log = tmp_path / "run.csv"
    log.write_text(with_battery(room_log_text()))
    args = ("inspect", str(log), "--sensors", "sonar[0-2]", "--start", "5", "--end", "10")
    code, stdout, _ = run(*args, "--json")
    assert code == 0
    doc = json.loads(stdout)
    assert doc["selection"] == {
        "sensors": ["sonar[0-2]"],
        "start": "5",
        "end": "10",
        "start_ns": 5_000_000_000,
        "end_ns": 10_000_000_000,
        "sensors_selected": 3,
        "sensors_in_log": 17,
        "sensor_names": "sonar0..sonar2",
    }
    assert doc["notes"] == []  # battery_v was not selected
    assert doc["log"]["readings"]["count"] == 3 * 50
    assert [s["name"] for s in doc["log"]["sensors"]] == ["sonar0", "sonar1", "sonar2"]
    code, stdout, _ = run(*args)
    assert code == 0
    assert "Selection (--sensors 'sonar[0-2]' --start 5 --end 10)" in stdout
    assert "  sensors   3 of 17: sonar0..sonar2" in stdout
    assert "  readings  from 5.000 s to 10.000 s (not including it)" in stdout
    code, stdout, _ = run("inspect", str(log))
    assert f"Warning: {log}: column 'battery_v' is not a range sensor" in stdout
    assert "-> ready to build" in stdout


def test_calibrate_takes_a_window(tmp_path: Path) -> None:
    log = str(SAMPLES / "corridor_loop.csv")
    code, stdout, stderr = run("calibrate", log, "--json")
    assert code == 0, stderr
    whole = json.loads(stdout)
    code, stdout, stderr = run("calibrate", log, "--json", "--start", "20", "--end", "80")
    assert code == 0, stderr
    part = json.loads(stdout)
    assert 0 < part["windows"]["total"] < whole["windows"]["total"]
    assert part["travel"]["driven_m"] < whole["travel"]["driven_m"]
    code, _, stderr = run("calibrate", log, "--sensors", "sonar*")
    assert code == 2 and "No such option '--sensors'" in stderr


def test_evaluate_scores_the_window_of_its_log(tmp_path: Path) -> None:
    log = str(SAMPLES / "corridor_loop.csv")
    world = str(SAMPLES / "worlds" / "corridor_loop.yaml")
    window = ("--start", "10", "--end", "60")
    assert run("build", log, "-o", str(tmp_path / "m.png"), "--quiet", *window)[0] == 0
    scores = []
    for extra in ((), window):
        code, stdout, stderr = run("evaluate", str(tmp_path / "m.yaml"), "--truth", world,
                                   "--log", log, "--json", *extra)  # fmt: skip
        assert code == 0, stderr
        scores.append(json.loads(stdout))
    # the region scored is what the window's sensors could have sensed: smaller
    assert scores[1]["cells"] < scores[0]["cells"]
    code, _, stderr = run("evaluate", str(tmp_path / "m.yaml"), "--truth", world,
                          "--frame", "world", "--start", "10")  # fmt: skip
    assert code == 2
    assert stderr.strip() == "Error: --sensors, --start and --end choose part of --log; give --log"


@pytest.mark.parametrize("flag", ["--start", "--end"])
def test_a_window_bound_no_stamp_holds_is_a_usage_error(tmp_path: Path, flag: str) -> None:
    csv = Path(__file__).resolve().parents[1] / "samples" / "corridor_loop.csv"
    out = tmp_path / "m.png"
    code, stdout, stderr = run("build", str(csv), "-o", str(out), flag, "1e300")
    assert (code, stdout) == (2, "") and not names(tmp_path)
    assert stderr == (
        f"Error: {flag} 1e300: '1e300' s is beyond what a nanosecond stamp holds "
        "(about 292 years from zero)\n"
    )
