"""Output blocks of the README and docs: what a command prints, shown as it prints it.

A block fenced as ``text output: gridmap ...`` shows the standard output of that command, run
from a clone (the repository's ``samples/`` in the working folder). tests/test_readme.py runs
each such command and compares; ``make doc-outputs`` (``python -m tests.doc_outputs``) runs
them and writes what they print now into the blocks, for when a change of output is intended.
Lines are compared without trailing spaces, and without blank lines at either end.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
#: The fence opening an output block, and the command whose standard output it shows.
INFO = "text output: "
OUTPUT_BLOCK = re.compile(rf"^```{INFO}(?P<command>[^\n]*)\n(?P<body>.*?)^```[ \t]*$", re.S | re.M)


@dataclass(frozen=True)
class OutputBlock:
    """One output block: the command, the text shown, and where the text is in the doc."""

    command: str
    shown: str
    start: int  # offset of the body's first character in the doc
    end: int  # offset just past the body's last newline


def output_blocks(text: str) -> list[OutputBlock]:
    """The output blocks of a Markdown ``text``, in order."""
    return [
        OutputBlock(m["command"].strip(), m["body"], m.start("body"), m.end("body"))
        for m in OUTPUT_BLOCK.finditer(text)
    ]


def normalised(text: str) -> str:
    """``text`` as compared: no trailing spaces, no blank lines at either end."""
    return "\n".join(line.rstrip() for line in text.splitlines()).strip("\n")


def shell(command: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``command`` run through bash in ``cwd`` as a reader of the docs runs it, with the
    ``gridmap`` installed beside this Python first on the PATH."""
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    return subprocess.run(
        ["bash", "-o", "pipefail", "-c", command],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def run_command(command: str, cwd: Path) -> str:
    """Standard output of ``command`` (a ``gridmap ...`` line) run by :func:`shell`; raises
    :class:`AssertionError` naming the command when it fails."""
    if not command.startswith("gridmap "):
        raise AssertionError(f"an output block shows a gridmap command, not {command!r}")
    done = shell(command, cwd)
    if done.returncode != 0:
        raise AssertionError(f"{command}: exit {done.returncode}\n{done.stderr}")
    return done.stdout


def regenerate(doc: Path, cwd: Path) -> bool:
    """Write what each output block's command prints now into ``doc``; True if it changed."""
    text = doc.read_text(encoding="utf-8")
    pieces: list[str] = []
    done = 0
    for block in output_blocks(text):
        pieces += [text[done : block.start], normalised(run_command(block.command, cwd)) + "\n"]
        done = block.end
    new = "".join(pieces) + text[done:]
    if new == text:
        return False
    doc.write_text(new, encoding="utf-8")
    return True


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="gridmap-docs-") as folder:
        cwd = Path(folder)
        (cwd / "samples").symlink_to(REPO / "samples")
        for doc in DOCS:
            if regenerate(doc, cwd):
                print(f"updated {doc.relative_to(REPO)}")


if __name__ == "__main__":
    main()
