"""``-`` as a file name: a text log from standard input, a map or log to standard output."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from gridmap_cli.cli import cli
from tests.helpers import names

SAMPLES = Path(__file__).resolve().parent.parent / "samples"
CSV = SAMPLES / "corridor_loop.csv"


def run_io(*args: str, stdin: bytes = b"") -> tuple[int, bytes, str]:
    result = CliRunner().invoke(cli, list(args), input=stdin)
    if result.exception and not isinstance(result.exception, SystemExit):
        raise result.exception
    return result.exit_code, result.stdout_bytes, result.stderr


def test_a_map_from_stdin_to_stdout_is_the_map_of_the_file(tmp_path: Path) -> None:
    code, image, err = run_io("build", "-", "-o", "-", "--fmt", "pgm", "-q", stdin=CSV.read_bytes())
    assert code == 0, err
    assert run_io("build", str(CSV), "-o", str(tmp_path / "m.pgm"), "-q")[0] == 0
    assert image == (tmp_path / "m.pgm").read_bytes()
    assert names(tmp_path) == {"m.pgm", "m.yaml"}


def test_gzipped_aria_from_stdin_converts_to_csv_on_stdout() -> None:
    aria = gzip.compress((SAMPLES / "corridor_loop.2d").read_bytes())
    code, out, err = run_io("convert", "-", "-", "--to", "csv", "-q", stdin=aria)
    assert code == 0, err
    assert out.startswith(b"# gridmap-csv: 1\n")
    assert out.count(b"\n") > 1000


def test_a_simulated_log_pipes_into_calibrate() -> None:
    world, path = (
        SAMPLES / "worlds" / "corridor_loop.yaml",
        SAMPLES / "paths" / "corridor_loop.yaml",
    )
    code, log, err = run_io("simulate", str(world), str(path), "-o", "-", "--to", "csv", "-q")
    assert code == 0, err
    code, out, err = run_io("calibrate", "-", "--json", stdin=log)
    assert code == 0, err
    assert b'"log": "-"' in out


def test_stdio_mistakes_are_one_line_usage_errors(tmp_path: Path) -> None:
    mcap = (SAMPLES / "corridor_loop.mcap").read_bytes()
    cases = [
        (
            ("build", "-", "-o", "-"),
            b"",
            "-o - writes the map image to standard output: give --fmt",
        ),
        (("build", "-", "-o", "-", "--fmt", "png", "--json"), b"", "--json would mix with it"),
        (("build", "-", "-o", str(tmp_path / "m.png")), mcap, "<stdin>: mcap logs cannot be read"),
        (("build", "-", "-o", str(tmp_path / "m.png")), b"hello\n", "<stdin>: cannot tell the log"),
        (("convert", "-", "-"), b"", "-: cannot tell the log format from the name"),
        (("build", "-", str(CSV), "-o", str(tmp_path / "m.png")), b"", "- (standard input) is one"),
    ]
    for args, stdin, message in cases:
        code, out, err = run_io(*args, stdin=stdin)
        assert code == 2, (args, err)
        assert err.startswith("Error: ") and err.count("\n") == 1 and message in err, err
        assert out == b""
    assert names(tmp_path) == set()


def _description(*args: str, stdin: bytes = b"") -> dict[str, object]:
    code, out, err = run_io("inspect", "--json", *args, stdin=stdin)
    assert code == 0, err
    doc: dict[str, object] = json.loads(out)
    return doc


@pytest.mark.parametrize(
    "sample, gzipped, fmt",
    [
        ("corridor_loop.csv", False, None),
        ("corridor_loop.csv", True, None),
        ("corridor_loop.2d", False, None),
        ("corridor_loop.2d", True, "aria"),
        ("hall.csv", False, "csv"),
    ],
)
def test_inspect_reads_standard_input_as_it_reads_the_file(
    sample: str, gzipped: bool, fmt: str | None
) -> None:
    """The README's table: ``-`` as a log is standard input, for inspect as for build."""
    data = (SAMPLES / sample).read_bytes()
    data = gzip.compress(data) if gzipped else data
    flags = ["--format", fmt] if fmt else []
    from_file = _description(str(SAMPLES / sample), *flags)
    from_stdin = _description("-", *flags, stdin=data)
    assert from_stdin.pop("file") == "<stdin>"
    assert from_stdin.pop("bytes") == len(data)
    from_file.pop("file"), from_file.pop("bytes")
    assert from_stdin == from_file


def test_a_carmen_log_on_standard_input_is_described(tmp_path: Path) -> None:
    from tests.corpus.generate import carmen_text

    (tmp_path / "run.log").write_text(carmen_text())
    from_file = _description(str(tmp_path / "run.log"))
    from_stdin = _description("-", stdin=carmen_text().encode())
    assert from_stdin["format"] == "carmen"
    assert from_stdin["log"] == from_file["log"] and from_stdin["build"] == from_file["build"]


@pytest.mark.parametrize(
    "args, stdin, code, message",
    [
        (["-"], (SAMPLES / "corridor_loop.mcap").read_bytes(), 2, "<stdin>: mcap logs cannot"),
        (["-", str(CSV)], CSV.read_bytes(), 2, "- (standard input) is one log"),
        (["-"], b"hello\n", 2, "<stdin>: cannot tell the log format"),
        (["-", "--odom-topic", "/odom"], CSV.read_bytes(), 2, "--odom-topic only applies"),
        (["-"], CSV.read_bytes().replace(b"\n0.1,", b"\nzero,", 1), 1, "<stdin>:"),
    ],
)
def test_inspect_refuses_what_standard_input_cannot_give(
    args: list[str], stdin: bytes, code: int, message: str
) -> None:
    got, out, err = run_io("inspect", *args, stdin=stdin)
    assert got == code, err
    assert out == b""
    assert err.count("\n") == 1 and err.startswith(f"Error: {message}"), err
