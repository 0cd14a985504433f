"""What an unattended run (cron) needs of every command (issue 11): one ``Error:`` line always,
no leftovers of a crashed run, and no silent nonsense."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
import yaml

from tests.helpers import names, run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
CSV = SAMPLES / "corridor_loop.csv"
WORLD = SAMPLES / "worlds" / "corridor_loop.yaml"
HALL = SAMPLES / "worlds" / "hall.yaml"
PATH = SAMPLES / "paths" / "corridor_loop.yaml"


def one_error_line(err: str) -> str:
    assert err.count("\n") == 1 and err.startswith("Error: "), err
    assert "Traceback" not in err and "Usage:" not in err
    return err.strip()


# ------------------------------------------------------------------------- one line, always


@pytest.mark.parametrize(
    ("args", "code", "text"),
    [
        (("build", str(CSV), "-o", "{dir}"), 2, "is a directory"),
        (("simulate", str(WORLD), str(PATH), "-o", "{dir}"), 2, "is a directory"),
        (("build", "{dir}", "-o", "{out}"), 1, "a directory, but not a rosbag2 folder"),
        (("build", str(CSV), "-o", "{out}", "--no-such-flag"), 2, "No such option"),
        (("build", "-o", "{out}"), 2, "Missing argument 'LOG...'"),
        (("nosuchcommand",), 2, "No such command"),
    ],
)
def test_click_usage_errors_are_one_line(
    tmp_path: Path, args: tuple[str, ...], code: int, text: str
) -> None:
    folder = tmp_path / "d"
    folder.mkdir()
    argv = [a.format(dir=folder, out=tmp_path / "m.png") for a in args]
    got, out, err = run(*argv)
    assert (got, out) == (code, "")
    assert text in one_error_line(err)


def test_a_rosbag2_folder_is_a_log_but_not_an_output(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    code, _, err = run("build", str(CSV), "-o", str(bag))
    assert code == 2 and "is a directory" in one_error_line(err)


@pytest.mark.parametrize(
    ("option", "text"),
    [
        ("--robot", "name: x\nsensors: [\n  - {a: 1\n"),
        ("--truth", "image: w.pgm\nresolution: [0.05\norigin: x\n"),
    ],
)
def test_yaml_syntax_errors_are_one_line_with_the_place(
    tmp_path: Path, option: str, text: str
) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    if option == "--robot":
        args = ["build", str(CSV), "-o", str(tmp_path / "m.png"), "--robot", str(bad)]
    else:
        args = ["evaluate", str(WORLD), "--truth", str(bad), "--frame", "world"]
    code, _, err = run(*args)
    line = one_error_line(err)
    assert code == 1
    assert line.startswith(f"Error: {bad}:3: not valid YAML: ") and "(column " in line


def test_a_broken_path_yaml_is_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "p.yaml"
    bad.write_text("gridmap-path: 1\nwaypoints: [[0, 0]\n")
    code, _, err = run("simulate", str(WORLD), str(bad), "-o", str(tmp_path / "s.csv"))
    assert code == 1 and one_error_line(err).startswith(f"Error: {bad}:")


# ------------------------------------------------------------------------------ leftovers


def test_build_cleans_what_a_killed_build_left_and_only_that(tmp_path: Path) -> None:
    out = tmp_path / "map.png"
    # what a build killed while writing leaves (a process id that no longer runs)
    dead = 2**22 + 12345
    leftovers = [
        tmp_path / f".map.png.tmp-{dead}-0123abcd.png",
        tmp_path / f".map.yaml.tmp-{dead}-4567cdef.yaml",
        tmp_path / f".map.png.bak-{dead}-89abcdef.png",
    ]
    others = [tmp_path / f".other.png.tmp-{dead}-0123abcd.png", tmp_path / ".map.png.keep"]
    for path in leftovers + others:
        path.write_bytes(b"x")
    code, _, err = run("build", str(CSV), "-o", str(out), "-q")
    assert code == 0, err
    assert names(tmp_path) == {"map.png", "map.yaml"} | {p.name for p in others}


# ------------------------------------------------------------------------- silent nonsense


def test_an_absurd_resolution_is_refused(tmp_path: Path) -> None:
    code, _, err = run("build", str(CSV), "-o", str(tmp_path / "m.png"), "--resolution", "1e6")
    assert code == 2
    assert one_error_line(err).startswith("Error: --resolution 1e+06 m: cells larger than 5 m")
    assert names(tmp_path) == set()


def test_a_map_too_big_names_the_log(tmp_path: Path) -> None:
    code, _, err = run("build", str(CSV), "-o", str(tmp_path / "m.png"), "--resolution", "1e-5")
    assert code == 1
    assert one_error_line(err).startswith(f"Error: {CSV}: the data spans ")


def test_an_aria_log_of_an_unknown_version_is_refused(tmp_path: Path) -> None:
    log = tmp_path / "v99.2d"
    text = (SAMPLES / "corridor_loop.2d").read_text(encoding="latin-1")
    log.write_text(text.replace("version: 4\n", "version: 99\n", 1), encoding="latin-1")
    code, _, err = run("build", str(log), "-o", str(tmp_path / "m.png"))
    assert code == 1
    assert one_error_line(err).startswith(
        f"Error: {log}:9: version '99': gridmap reads LaserOdometryLog versions 1, 2, 3, 4"
    )


@pytest.fixture(scope="module")
def corridor_maps(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("maps")
    for name, extra in (("c", ()), ("coarse", ("--resolution", "0.1"))):
        code, _, err = run("build", str(CSV), "-o", str(folder / f"{name}.png"), "-q", *extra)
        assert code == 0, err
    code, _, err = run(
        "build", str(SAMPLES / "hall.csv"), "-o", str(folder / "h.png"), "-q", "--pose", "global"
    )
    assert code == 0, err
    return folder


def test_evaluate_refuses_a_truth_world_of_another_place(corridor_maps: Path) -> None:
    code, out, err = run("evaluate", str(corridor_maps / "c.yaml"), "--truth", str(HALL),
                         "--log", str(CSV))  # fmt: skip
    assert (code, out) == (1, "")
    line = one_error_line(err)
    assert line.startswith(f"Error: {CSV}: only ") and f"truth world {HALL}" in line


def test_evaluate_refuses_a_map_mostly_outside_the_world(corridor_maps: Path) -> None:
    # the hall map, placed 100 m away by its YAML origin
    moved = corridor_maps / "far.yaml"
    doc = yaml.safe_load((corridor_maps / "h.yaml").read_text())
    doc["origin"][0] += 100.0
    doc["image"] = "far.png"
    shutil.copy(corridor_maps / "h.png", corridor_maps / "far.png")
    moved.write_text(yaml.safe_dump(doc))
    code, _, err = run("evaluate", str(moved), "--truth", str(HALL), "--frame", "world")
    assert code == 1
    assert "of its known cells fall inside the truth world" in one_error_line(err)


def test_evaluate_warns_of_another_resolution(corridor_maps: Path) -> None:
    code, _, err = run("evaluate", str(corridor_maps / "coarse.yaml"), "--truth", str(WORLD),
                       "--log", str(CSV))  # fmt: skip
    assert code == 0
    assert (
        f"Warning: {corridor_maps / 'coarse.yaml'}: resolution 0.1 m, the truth world {WORLD} "
        "0.05 m" in err
    )


def test_evaluate_of_the_right_world_says_nothing(corridor_maps: Path) -> None:
    code, _, err = run("evaluate", str(corridor_maps / "c.yaml"), "--truth", str(WORLD),
                       "--log", str(CSV))  # fmt: skip
    assert (code, err) == (0, "")


def test_unexpected_exceptions_are_one_line_without_debug(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from gridmap_cli.mapping import pipeline  # the build's mapping

    def boom(*args: object, **kwargs: object) -> None:
        raise MemoryError

    monkeypatch.setattr(pipeline, "build_map", boom)
    code, _, err = run("build", str(CSV), "-o", str(tmp_path / "m.png"))
    assert code == 1 and "out of memory" in one_error_line(err)
    monkeypatch.setattr(pipeline, "build_map", lambda *a, **k: [][1])
    code, _, err = run("build", str(CSV), "-o", str(tmp_path / "m.png"))
    assert code == 1 and "internal error (IndexError" in one_error_line(err)
    assert os.listdir(tmp_path) == []


def test_gridmap_alone_still_prints_its_help() -> None:
    code, out, err = run()
    assert "[OPTIONS] COMMAND [ARGS]..." in out + err and "Commands:" in out + err
    assert "Error" not in out + err
    assert code in (0, 2)  # click 8.1 exits 0, click 8.2 exits 2
