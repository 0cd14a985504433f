"""What a script can rely on across commands: --json and -q where a command reports, JSON
numbers as people write them, --format always the input's format."""

from __future__ import annotations

import importlib
import json
import re
from pathlib import Path

import pytest

from tests.helpers import names, run

REPO = Path(__file__).resolve().parent.parent
SAMPLES = REPO / "samples"
CSV = SAMPLES / "corridor_loop.csv"


def noisy(doc: object) -> list[float]:
    """Floats in ``doc`` printed with more than 12 significant digits (54.01999999999933)."""
    if isinstance(doc, dict):
        return [x for v in doc.values() for x in noisy(v)]
    if isinstance(doc, list):
        return [x for v in doc for x in noisy(v)]
    if isinstance(doc, float):
        digits = re.sub(r"e.*|[-.]", "", repr(doc)).lstrip("0")
        return [doc] if len(digits) > 12 else []
    return []


def test_every_reporting_command_has_json_without_float_noise(tmp_path: Path) -> None:
    world = SAMPLES / "worlds" / "corridor_loop.yaml"
    path = SAMPLES / "paths" / "corridor_loop.yaml"
    runs = {
        "build": ("build", str(CSV), "-o", str(tmp_path / "m.png"), "-q"),
        "inspect": ("inspect", str(CSV)),
        "calibrate": ("calibrate", str(CSV)),
        "convert": ("convert", str(CSV), str(tmp_path / "c.mcap"), "-q"),
        "simulate": ("simulate", str(world), str(path), "-o", str(tmp_path / "s.csv"), "-q"),
        "evaluate": (
            "evaluate",
            str(tmp_path / "m.yaml"),
            "--truth",
            str(world),
            "--log",
            str(CSV),
        ),
    }
    for name, args in runs.items():
        code, out, err = run(*args, "--json")
        assert code == 0, (name, err)
        doc = json.loads(out)
        assert isinstance(doc, dict) and doc, name
        assert noisy(doc) == [], name
    assert json.loads(run(*runs["convert"][:3], "--json", "--force", "-q")[1])["readings"] > 0


def test_quiet_silences_the_report(tmp_path: Path) -> None:
    out = tmp_path / "odometry.yaml"
    code, stdout, stderr = run("calibrate", str(CSV), "-o", str(out), "-q")
    assert (code, stdout, stderr) == (0, "", "")
    assert out.is_file()
    code, stdout, stderr = run("build", str(CSV), "-o", str(tmp_path / "m.png"), "-q")
    assert (code, stdout, stderr) == (0, "", "")
    world = SAMPLES / "worlds" / "corridor_loop.yaml"
    code, stdout, stderr = run("evaluate", str(tmp_path / "m.yaml"), "--truth", str(world),
                               "--log", str(CSV), "-q")  # fmt: skip
    assert (code, stdout, stderr) == (0, "", "")


def test_format_names_the_input_everywhere_and_to_the_output(tmp_path: Path) -> None:
    renamed = tmp_path / "run.txt"
    renamed.write_bytes(CSV.read_bytes())
    out = tmp_path / "run.bin"
    code, _, err = run("convert", str(renamed), str(out), "--format", "csv", "--to", "mcap", "-q")
    assert code == 0, err
    code, stdout, _ = run("inspect", str(out), "--format", "mcap", "--json")
    assert json.loads(stdout)["format"] == "mcap"
    assert names(tmp_path) == {"run.txt", "run.bin"}


def test_ctrl_c_exits_130_with_one_line_and_no_output(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pipeline = importlib.import_module("gridmap_cli.mapping.pipeline")  # the build's mapping

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline, "build_map", interrupted)
    code, _, err = run("build", str(CSV), "-o", str(tmp_path / "m.png"))
    assert code == 130
    assert err == "Error: interrupted (Ctrl-C); no output was written or changed\n"
    assert names(tmp_path) == set()
