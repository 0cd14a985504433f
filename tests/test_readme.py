"""The examples in the README and docs run as written, with the installed ``gridmap`` command.

Code blocks fenced as ``sh`` are run, line by line, in a fresh folder that holds the repository's
``samples/`` (as a newcomer runs them from a clone); blocks fenced ``sh placeholders`` name files
the reader has to supply and are not run. Blocks fenced ``text output: gridmap ...`` show what
that command prints, and must show what it prints now (tests/doc_outputs.py; ``make doc-outputs``
rewrites them). This is also the smoke test of the installed command: it runs through the shell,
from the PATH the README tells users to set up.
"""

from __future__ import annotations

import re
import sys
import tomllib
from pathlib import Path

import pytest

from tests.doc_outputs import normalised, output_blocks, run_command, shell

REPO = Path(__file__).resolve().parent.parent
DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
BLOCK = re.compile(r"^```(?P<info>[^\n]*)\n(?P<body>.*?)^```", re.S | re.M)


def examples(doc: Path) -> list[tuple[str, str | None]]:
    """The command lines of ``doc``'s runnable blocks (``gridmap ...``, and the ``mkdir`` of the
    output folder; continuation lines joined), each with the summary line the doc shows after
    it (a ``# gridmap: ...`` comment line), if any."""
    lines: list[tuple[str, str | None]] = []
    for block in BLOCK.finditer(doc.read_text(encoding="utf-8")):
        if block["info"].strip() != "sh":
            continue
        for line in block["body"].replace("\\\n", " ").splitlines():
            if line.startswith(("gridmap ", "mkdir ")):
                lines.append((line, None))
            elif line.startswith("# gridmap: ") and lines:
                lines[-1] = (lines[-1][0], line.removeprefix("# "))
    return lines


def test_the_readme_says_how_gridmap_gets_on_the_path() -> None:
    text = (REPO / "README.md").read_text(encoding="utf-8")
    assert ". .venv/bin/activate" in text and "pipx install ." in text
    assert (Path(sys.executable).parent / "gridmap").exists(), "gridmap is installed beside python"


@pytest.mark.parametrize("doc", DOCS, ids=[d.name for d in DOCS])
def test_examples_run_as_written(doc: Path, tmp_path: Path) -> None:
    commands = examples(doc)
    if not commands:
        pytest.skip(f"{doc.name} has no runnable examples")
    (tmp_path / "samples").symlink_to(REPO / "samples")
    for command, shown in commands:
        done = shell(command, tmp_path)
        assert done.returncode == 0, f"{doc.name}: {command}\n{done.stderr}"
        if shown is not None:  # the doc shows what the command says: it must say that
            assert done.stderr.strip().splitlines()[-1] == shown
    # run from a clone, the examples write only into out/, which git ignores
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "samples"]


def test_the_readme_use_block_runs_twice(tmp_path: Path) -> None:
    """A newcomer runs the Use block, edits a line and runs it again: every line that writes
    says --force, so the second run overwrites instead of failing."""
    (tmp_path / "samples").symlink_to(REPO / "samples")
    commands = examples(REPO / "README.md")
    for command, _ in commands:
        assert shell(command, tmp_path).returncode == 0, command
    for command, _ in commands:
        done = shell(command, tmp_path)
        assert done.returncode == 0, f"second run: {command}\n{done.stderr}"


OUTPUT_DOCS = [d for d in DOCS if output_blocks(d.read_text(encoding="utf-8"))]


def test_the_calibrate_figures_are_an_output_block() -> None:
    """The sample output of docs/odometry-error.md is checked, not merely shown."""
    blocks = output_blocks((REPO / "docs" / "odometry-error.md").read_text(encoding="utf-8"))
    assert [b.command for b in blocks] == ["gridmap calibrate samples/corridor_loop.csv"]


@pytest.mark.parametrize("doc", OUTPUT_DOCS, ids=[d.name for d in OUTPUT_DOCS])
def test_output_blocks_show_what_the_command_prints(doc: Path, tmp_path: Path) -> None:
    (tmp_path / "samples").symlink_to(REPO / "samples")
    for block in output_blocks(doc.read_text(encoding="utf-8")):
        printed = normalised(run_command(block.command, tmp_path))
        assert printed == normalised(block.shown), (
            f"{doc.name}: the block of `{block.command}` is stale (make doc-outputs rewrites it)"
        )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["samples"]


def test_the_plot_examples_say_how_to_install_the_plot_extra() -> None:
    install = "pip install 'gridmap-cli[plot]'"
    with open(REPO / "pyproject.toml", "rb") as handle:
        extras = tomllib.load(handle)["project"]["optional-dependencies"]
    assert any(dep.startswith("matplotlib") for dep in extras["plot"])
    for doc in (REPO / "README.md", REPO / "docs" / "evaluation.md"):
        text = doc.read_text(encoding="utf-8")
        assert install in text.replace("\n", " "), doc.name
