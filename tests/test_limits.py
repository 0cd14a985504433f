"""Memory bombs are refused before they are held in memory, naming the limit hit (issue 11): one
CSV row of 50 million fields, a ``sonar:`` line of 10^8 values, a robot laser of 10^8 samples,
simulations numpy cannot allocate.

What is asserted is the memory the refusal took (Python's and numpy's allocations, traced), not
its time: a loaded machine made the old "under a second" checks fail for the wrong reason."""

from __future__ import annotations

import io
import tracemalloc
from pathlib import Path

import pytest

from gridmap_cli.limits import (
    MAX_LASER_SAMPLES,
    MAX_LINE_CHARS,
    MAX_SETTINGS_BYTES,
    LimitError,
    numbered_lines,
    read_bounded_text,
)
from tests.helpers import names, run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
CSV = SAMPLES / "corridor_loop.csv"


class EndlessLine(io.StringIO):
    """A text handle whose first line never ends: what a reader that reads whole lines would
    spend all memory on."""

    def readline(self, size: int | None = -1) -> str:  # type: ignore[override]
        assert size is not None and 0 < size <= MAX_LINE_CHARS + 1, "an unbounded read"
        return "1," * (size // 2) + "1" * (size % 2)


#: What a refused bomb may allocate at its peak: the reader's first MiB of the line (as text and
#: as the list a split makes of it) and the command's own set-up, far below the bombs' 50 MB to
#: gigabytes.
REFUSAL_PEAK_BYTES = 48 * 2**20


def refused(tmp_path: Path, *args: str) -> tuple[str, int]:
    """Run a command that must be refused; returns its one-line error and the peak bytes it
    allocated."""
    before = names(tmp_path)
    tracemalloc.start()
    try:
        code, out, err = run(*args)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert (code, out) == (1, ""), err
    assert err.count("\n") == 1, err
    assert names(tmp_path) == before
    return err, peak


def test_a_line_without_end_is_refused_after_reading_the_limit() -> None:
    with pytest.raises(LimitError) as info:
        list(numbered_lines(EndlessLine(), "endless.csv"))
    assert str(info.value).startswith("endless.csv:1: line longer than 1,048,576 characters")
    assert "MAX_LINE_CHARS" in str(info.value)


def test_a_csv_row_of_50_million_fields_is_refused_unheld(tmp_path: Path) -> None:
    log = tmp_path / "bomb.csv"
    with open(log, "w") as handle:
        handle.write("time,x,y,theta,s0\n0,0,0,0,1\n")
        handle.write("," * 50_000_000 + "\n")
    err, peak = refused(tmp_path, "build", str(log), "-o", str(tmp_path / "m.png"))
    assert err.startswith(f"Error: {log}:3: line longer than {MAX_LINE_CHARS:,} characters")
    assert peak < REFUSAL_PEAK_BYTES


def test_a_sonar_line_of_ten_million_values_is_refused_unheld(tmp_path: Path) -> None:
    # 10^8 values would be 700 MB on disk; the reader stops after the first MiB either way
    # (test_a_line_without_end... shows a line of any length is read only that far)
    log = tmp_path / "bomb.2d"
    with open(log, "w") as handle:
        handle.write("LaserOdometryLog\nversion: 4\nsonarUnit: 0 147 136 90\nlogTime: 0.0\n")
        handle.write("robot: 0 0 0\nsonar: " + "0 1000 " * 10_000_000 + "\n")
    err, peak = refused(tmp_path, "build", str(log), "-o", str(tmp_path / "m.png"))
    assert err.startswith(f"Error: {log}:6: line longer than")
    assert peak < REFUSAL_PEAK_BYTES


def test_a_carmen_line_too_long_is_refused(tmp_path: Path) -> None:
    log = tmp_path / "bomb.log"
    log.write_text("ODOM 0 0 0 0 0 0 1.0 host 1.0\nFLASER 181 " + "1.0 " * 400_000 + "\n")
    err, _ = refused(tmp_path, "build", str(log), "-o", str(tmp_path / "m.png"))
    assert err.startswith(f"Error: {log}:2: line longer than")


def test_a_robot_laser_of_a_hundred_million_samples_is_refused(tmp_path: Path) -> None:
    robot = tmp_path / "bomb.yaml"
    robot.write_text(
        "gridmap-robot: 1\nname: big\nsensors:\n"
        "  - {name: laser1, kind: laser, x_m: 0.16, y_m: 0.0, yaw_deg: 0,\n"
        "     first_deg: -90, last_deg: 90, samples: 100000000, max_range_m: 8.0}\n"
    )
    err, peak = refused(
        tmp_path, "build", str(CSV), "--robot", str(robot), "-o", str(tmp_path / "m.png")
    )
    assert err.strip() == (
        f"Error: {robot}:4: sensor 'laser1': 100,000,000 samples, above gridmap's limit of "
        f"{MAX_LASER_SAMPLES:,} beams per laser (MAX_LASER_SAMPLES)"
    )
    assert peak < REFUSAL_PEAK_BYTES


def test_an_aria_laser_conf_of_a_hundred_million_samples_is_refused(tmp_path: Path) -> None:
    log = tmp_path / "bomb.2d"
    log.write_text("LaserOdometryLog\nversion: 4\nsick1conf: -90 90 100000000\n")
    err, _ = refused(tmp_path, "build", str(log), "-o", str(tmp_path / "m.png"))
    assert err.startswith(f"Error: {log}:3: sick1conf: 100000000 samples, above gridmap's limit")


def test_a_huge_robot_file_is_refused_unread(tmp_path: Path) -> None:
    robot = tmp_path / "huge.yaml"
    with open(robot, "wb") as handle:
        handle.truncate(MAX_SETTINGS_BYTES + 1)  # sparse: costs no disk
    err, _ = refused(
        tmp_path, "build", str(CSV), "--robot", str(robot), "-o", str(tmp_path / "m.png")
    )
    assert "above gridmap's limit of" in err and "(MAX_SETTINGS_BYTES)" in err


@pytest.mark.parametrize(
    "flags", [("--rate", "1e12"), ("--duration", "1e15"), ("--rate", "1e300", "--duration", "1e9")]
)
def test_a_simulation_numpy_cannot_allocate_is_one_line(tmp_path: Path, flags: tuple[str]) -> None:
    world = SAMPLES / "worlds" / "corridor_loop.yaml"
    path = SAMPLES / "paths" / "corridor_loop.yaml"
    err, peak = refused(tmp_path, "simulate", str(world), str(path), "-o",
                           str(tmp_path / "s.csv"), *flags)  # fmt: skip
    assert err.startswith(f"Error: {path}: driving it ")
    assert "above gridmap's limit of" in err and "MAX_SIM_READINGS" in err
    assert peak < REFUSAL_PEAK_BYTES


def test_a_path_of_absurd_coordinates_is_one_line(tmp_path: Path) -> None:
    world = SAMPLES / "worlds" / "corridor_loop.yaml"
    path = tmp_path / "far.yaml"
    path.write_text("gridmap-path: 1\nwaypoints: [[2.0, 2.0], [2.0e+300, 2.0]]\n")
    err, _ = refused(tmp_path, "simulate", str(world), str(path), "-o", str(tmp_path / "s.csv"))
    assert err.startswith("Error: ")


@pytest.mark.parametrize("piece_chars", [7, 64, 1 << 22])
def test_bounded_text_names_the_long_line_wherever_the_pieces_cut(
    monkeypatch: pytest.MonkeyPatch, piece_chars: int
) -> None:
    monkeypatch.setattr("gridmap_cli.limits.MAX_LINE_CHARS", 20)
    monkeypatch.setattr("gridmap_cli.limits._PIECE_CHARS", piece_chars)
    fine = "a,b\r\n" + "1,2\n" * 30 + "x" * 20 + "\n"
    assert read_bounded_text(io.StringIO(fine), "ok.csv") == fine
    for lines_before in (0, 3, 17):
        text = "1,2\n" * lines_before + "x" * 21 + "\n1,2\n"
        with pytest.raises(LimitError) as info:
            read_bounded_text(io.StringIO(text), "bomb.csv")
        assert str(info.value).startswith(f"bomb.csv:{lines_before + 1}: line longer than 20")


def test_bounded_text_stops_reading_an_endless_line() -> None:
    class Endless(io.StringIO):
        read_chars = 0

        def read(self, size: int | None = -1) -> str:
            assert size is not None and size > 0, "an unbounded read"
            self.read_chars += size
            return "," * size

    handle = Endless()
    with pytest.raises(LimitError):
        read_bounded_text(handle, "endless.csv")
    assert handle.read_chars <= MAX_LINE_CHARS + (1 << 22)


def _blank_bomb(path: Path, head: str, line: bytes, gz: bool) -> None:
    """``head`` then 64 MiB of ``line`` (an empty or blank line), gzip-compressed if ``gz``."""
    import gzip

    body = head.encode() + line * ((64 << 20) // len(line))
    if gz:
        path.write_bytes(gzip.compress(body, compresslevel=1))
    else:
        path.write_bytes(body)


@pytest.mark.parametrize(
    ("name", "head", "line", "command"),
    [
        ("bomb.csv.gz", "", b"\n", "build"),
        ("bomb.csv.gz", "time,x,y,theta,s0\n", b"\n", "build"),
        ("bomb.csv.gz", "time,x,y,theta,s0\n", b"   \n", "inspect"),
        ("bomb.csv.gz", "time,x,y,theta,s0\r\n", b"\r\n", "build"),
        ("bomb.csv", "time,x,y,theta,s0\n", b"\n", "build"),
        ("bomb.log.gz", "# CARMEN\n", b"\n", "inspect"),
        ("bomb.2d", "LaserOdometryLog\nversion: 4\n", b" \n", "build"),
    ],
)  # fmt: skip
def test_a_log_of_empty_lines_is_refused_unheld(
    tmp_path: Path, name: str, head: str, line: bytes, command: str
) -> None:
    # a few GiB of newlines gzip to a few MiB; each line held cost a list slot and a pass of
    # the row reader: 1 GiB of them took 6 GB and minutes before the bound
    from gridmap_cli.limits import MAX_BLANK_LINES

    log = tmp_path / "logs" / name
    log.parent.mkdir()
    _blank_bomb(log, head, line, name.endswith(".gz"))
    args = ["-o", str(tmp_path / "m.png")] if command == "build" else []
    err, peak = refused(tmp_path, command, str(log), *args)
    assert err.startswith(f"Error: {log}:")
    assert f"more than {MAX_BLANK_LINES:,} empty lines" in err and "MAX_BLANK_LINES" in err
    assert peak < 3 * REFUSAL_PEAK_BYTES


def test_a_real_log_with_a_few_blank_lines_still_reads(tmp_path: Path) -> None:
    log = tmp_path / "gaps.csv"
    text = CSV.read_text().split("\n")
    log.write_text("\n".join([*text[:50], "", "  ", "", *text[50:]]))
    code, _, err = run("build", str(log), "-o", str(tmp_path / "m.png"), "-q")
    assert code == 0, err
