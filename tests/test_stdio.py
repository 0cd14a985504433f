"""``-`` as a file name: a text log from standard input, a map or log to standard output."""

from __future__ import annotations

import gzip
from pathlib import Path

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
