"""The streamed readers (``csv_stream.py``, ``mcap/stream.py``) are checked as the held ones
are: stamps that do not advance or jump by years give the same warning, and refuse a time
window, whether the readings are held or streamed; a gzip bomb read by the streamed CSV path is
refused within the line limit (issue 21)."""

from __future__ import annotations

import tracemalloc
import zlib
from pathlib import Path

import pytest

from gridmap_cli.errors import InputFileError
from gridmap_cli.limits import MAX_LINE_CHARS
from gridmap_cli.mapping import pipeline
from gridmap_cli.mapping.stamps import stamp_problem
from gridmap_cli.readers import read_log
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros.mcap import stream as mcap_stream
from gridmap_cli.readers.text import csv_stream
from tests.helpers import run
from tests.readers.mcap_helpers import S
from tests.readers.test_mcap_stream import sonar_recording

STREAM = ReadOptions(stream=True)
YEARS_40_NS = 40 * 365 * 86_400 * 1_000_000_000
HEAD = "# robot: p3dx\ntime,x,y,theta,sonar0,sonar1\n"


@pytest.fixture
def streaming(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(csv_stream, "STREAM_FROM_BYTES", 0)
    monkeypatch.setattr(csv_stream, "PIECE_CHARS", 3_000)
    monkeypatch.setattr(mcap_stream, "STREAM_FROM_BYTES", 0)
    monkeypatch.setattr(pipeline, "SYNC_CHUNK_READINGS", 700)


def _csv(tmp_path: Path, seconds: list[float]) -> Path:
    rows = [f"{t:.6f},{k * 0.01:.2f},0.0,0.0,1.5,2.0\n" for k, t in enumerate(seconds)]
    path = tmp_path / "log.csv"
    path.write_text(HEAD + "".join(rows))
    return path


def _held_and_streamed(path: Path) -> tuple[str | None, str | None]:
    held, streamed = read_log(path), read_log(path, None, STREAM)
    assert held.stream is None and streamed.stream is not None  # the streamed path it is
    return stamp_problem(held), stamp_problem(streamed)


CSV_STAMPS = {
    "do not advance": [5.0 + k * 1e-6 for k in range(400)],
    "jump by": [k * 0.1 + (1.3e9 if k >= 200 else 0.0) for k in range(400)],
}


@pytest.mark.usefixtures("streaming")
@pytest.mark.parametrize("what", sorted(CSV_STAMPS))
def test_a_streamed_csv_log_has_the_held_ones_stamp_problem(what: str, tmp_path: Path) -> None:
    path = _csv(tmp_path, CSV_STAMPS[what])
    held, streamed = _held_and_streamed(path)
    assert held is not None and what in held
    assert streamed == held
    code, _, err = run("build", str(path), "-o", str(tmp_path / "m.png"), "--end", "10")
    assert code == 1 and err.count("\n") == 1 and "--end 10 cannot be honoured" in err, err
    assert not (tmp_path / "m.png").exists()


MCAP_STAMPS = {
    # the sonar's header stamps jump by 40 years half way (its odometry does not)
    "jump by": [S + k * S // 100 + (YEARS_40_NS if k >= 30 else 0) for k in range(60)],
}


@pytest.mark.usefixtures("streaming")
@pytest.mark.parametrize("what", sorted(MCAP_STAMPS))
def test_a_streamed_recording_has_the_held_ones_stamp_problem(what: str, tmp_path: Path) -> None:
    path = sonar_recording(tmp_path / "run.mcap", MCAP_STAMPS[what])
    held, streamed = _held_and_streamed(path)
    assert held is not None and what in held and streamed is not None
    # the same jump, from the same stamp; the streamed readings know their sensor's last stamp,
    # not the first after the jump
    assert streamed.partition(" to ")[0] == held.partition(" to ")[0]
    code, _, err = run("inspect", str(path), "--end", "0.5")
    assert code == 1 and "--end 0.5 cannot be honoured" in err, err


def test_good_streamed_stamps_have_no_problem(tmp_path: Path, streaming: None) -> None:
    path = _csv(tmp_path, [k * 0.1 for k in range(400)])
    assert _held_and_streamed(path) == (None, None)
    mcap = sonar_recording(tmp_path / "run.mcap", [S + k * S // 100 for k in range(60)])
    assert _held_and_streamed(mcap) == (None, None)


def _bomb(path: Path, head: bytes, block: bytes, blocks: int) -> Path:
    packer = zlib.compressobj(9, zlib.DEFLATED, 31)  # gzip
    with open(path, "wb") as out:
        out.write(packer.compress(head))
        for _ in range(blocks):
            out.write(packer.compress(block))
        out.write(packer.flush())
    return path


@pytest.mark.parametrize(
    "name, block",
    [("endless-line", b"1" * (1 << 20)), ("nuls", b"\0" * (1 << 20)),
     ("fields", b",2" * (1 << 19))],
)  # fmt: skip
def test_a_gzip_bomb_on_the_streamed_path_stops_within_the_line_limit(
    name: str, block: bytes, tmp_path: Path
) -> None:
    head = (HEAD + "0.0,0,0,0,1.5,2.0\n" * 5).encode()
    path = _bomb(tmp_path / f"{name}.csv.gz", head, block, 64)  # 64 MiB of text, one line
    assert csv_stream._text_bytes(path, True) >= csv_stream.STREAM_FROM_BYTES  # it streams
    tracemalloc.start()
    try:
        with pytest.raises(InputFileError, match="MAX_LINE_CHARS") as caught:
            read_log(path, None, STREAM)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert str(caught.value).startswith(f"{path}:8: ")
    assert peak < 12 * MAX_LINE_CHARS  # a few lines' worth, never the 64 MiB
