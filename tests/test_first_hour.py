"""What a new user types on the first try, and the word that sets it right: a command name
from other tools, an option's prefix, a topic without its slash, a map into a folder not made
yet, the preview's name, the presets, and a file that is no log."""

from __future__ import annotations

from pathlib import Path

from gridmap_cli.robot import preset_names
from tests.helpers import names, run

SAMPLES = Path(__file__).resolve().parent.parent / "samples"
CSV = SAMPLES / "corridor_loop.csv"
ROS2 = SAMPLES / "corridor_loop_ros2.mcap"


def test_info_points_to_inspect() -> None:
    code, _, err = run("info", str(CSV))
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("Error: No such command 'info'") and "gridmap inspect LOG" in err


def test_an_option_prefix_suggests_the_options_it_begins(tmp_path: Path) -> None:
    code, _, err = run("build", str(CSV), "--res", "0.1", "-o", str(tmp_path / "m.png"))
    assert code == 2 and err.count("\n") == 1
    assert "--resolution" in err
    assert names(tmp_path) == set()


def test_a_topic_without_its_leading_slash_is_the_root_namespaces(tmp_path: Path) -> None:
    maps = {}
    for topic in ("/sonar", "sonar"):
        out = tmp_path / f"{topic.strip('/')}{len(topic)}.pgm"
        code, _, err = run("build", str(ROS2), "--range-topic", topic, "-o", str(out), "-q")
        assert code == 0, err
        maps[topic] = out.read_bytes()
    assert maps["sonar"] == maps["/sonar"]
    code, _, err = run("build", str(ROS2), "--range-topic", "sonr", "-o", str(tmp_path / "x.png"))
    assert code == 2 and "--range-topic sonr: no such topic" in err


def test_o_and_f_make_the_maps_folder_and_a_file_in_the_way_is_an_error(tmp_path: Path) -> None:
    code, _, err = run("build", str(CSV), "-f", str(tmp_path / "maps" / "run"), "-q")
    assert code == 0, err
    assert names(tmp_path / "maps") == {"run.pgm", "run.yaml"}
    code, _, err = run("build", str(CSV), "-o", str(tmp_path / "a" / "b" / "run.png"), "-q")
    assert code == 0, err
    assert names(tmp_path / "a" / "b") == {"run.png", "run.yaml"}
    (tmp_path / "file").write_text("not a folder")
    code, _, err = run("build", str(CSV), "-o", str(tmp_path / "file" / "run.png"))
    assert code == 1 and err.strip().endswith(f"{tmp_path / 'file'} is not a directory")


def test_the_summary_names_the_draw_path_image(tmp_path: Path) -> None:
    out = tmp_path / "truth.png"
    code, _, err = run("build", str(CSV), "-o", str(out), "--pose", "global", "--draw-path")
    assert code == 0, err
    preview = tmp_path / "truth_path.png"
    assert preview.is_file() and f", {preview} (the tracks drawn on the map)" in err


def test_robot_help_lists_every_preset() -> None:
    for command in ("build", "batch"):
        code, out, _ = run(command, "--help")
        assert code == 0
        flat = " ".join(out.split())
        assert f"Robot preset ({', '.join(preset_names())})" in flat, command
    assert "p3at-lms200" in preset_names()


def test_a_file_that_is_no_log_says_what_was_found(tmp_path: Path) -> None:
    notes = tmp_path / "notes.txt"
    notes.write_text("Buy milk and eggs\nCall Bob\n")
    code, _, err = run("build", str(notes), "-o", str(tmp_path / "m.png"))
    assert code == 2 and err.count("\n") == 1
    assert "its first line 'Buy milk and eggs' is no CSV header (time,x,y,theta,...)" in err
    assert names(tmp_path) == {"notes.txt"}


def test_a_one_row_log_warns_that_no_cell_passes_the_thresholds(tmp_path: Path) -> None:
    lines = CSV.read_text().splitlines()
    header = [ln for ln in lines if ln.startswith("#")]
    rows = [ln for ln in lines if not ln.startswith("#")]
    one = tmp_path / "one.csv"
    one.write_text("\n".join([*header, *rows[:2]]) + "\n")  # the column names and one row
    out = tmp_path / "one.png"
    code, _, err = run("build", str(one), "-o", str(out))
    assert code == 0 and out.is_file()
    warning, summary = err.strip().splitlines()
    assert warning.startswith("Warning: none of the ")
    assert "passes --occupied 0.65 or --free 0.25: the evidence is too weak" in warning
    assert summary.startswith("gridmap: 16 of 16 readings mapped")
    code, _, err = run("build", str(CSV), "-o", str(tmp_path / "whole.png"))
    assert code == 0 and "Warning" not in err  # a whole run's map has walls and free space
