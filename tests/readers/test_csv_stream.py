"""Long CSV logs with their readings left in the file: the held log's readings and map, bit for
bit, and the held reader's errors."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.errors import InputFileError
from gridmap_cli.mapping import pipeline
from gridmap_cli.readers import read_log
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.text import csv_stream
from gridmap_cli.records import RangeReadings
from tests.helpers import built, names, run

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
LOG = SAMPLES / "corridor_loop.csv"
STREAM = ReadOptions(stream=True)


@pytest.fixture
def streaming(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every CSV log streams, in pieces of a few rows, and build cuts chunks of a few scans."""
    monkeypatch.setattr(csv_stream, "STREAM_FROM_BYTES", 0)
    monkeypatch.setattr(csv_stream, "PIECE_CHARS", 3_000)
    monkeypatch.setattr(pipeline, "SYNC_CHUNK_READINGS", 700)


def joined(blocks: list[RangeReadings]) -> RangeReadings:
    return RangeReadings(
        np.concatenate([b.stamp_ns for b in blocks]),
        np.concatenate([b.sensor for b in blocks]),
        np.concatenate([b.range_m for b in blocks]),
    )


def same_readings(a: RangeReadings, b: RangeReadings) -> bool:
    pairs = zip((a.stamp_ns, a.sensor, a.range_m), (b.stamp_ns, b.sensor, b.range_m), strict=True)
    return all(x.dtype == y.dtype and np.array_equal(x, y) for x, y in pairs)


@pytest.mark.usefixtures("streaming")
@pytest.mark.parametrize("gz", [False, True])
def test_a_streamed_log_reads_as_the_held_one(tmp_path: Path, gz: bool) -> None:
    path = LOG
    if gz:
        path = tmp_path / "run.csv.gz"
        path.write_bytes(gzip.compress(LOG.read_bytes()))
    held = read_log(path)
    streamed = read_log(path, None, STREAM)
    assert held.stream is None and streamed.stream is not None
    assert len(streamed.readings) == 0 and streamed.reading_count == len(held.readings)
    assert streamed.reading_span() == held.reading_span()
    for _ in range(2):  # read again for each pass
        assert same_readings(joined(list(streamed.stream.readings())), held.readings)
    chunks = [len(c) for c in streamed.reading_chunks(700)]
    assert chunks == [len(c) for c in held.reading_chunks(700)] and len(chunks) > 10
    for a, b in ((held.poses, streamed.poses), (held.truth, streamed.truth)):
        assert a is not None and b is not None
        assert all(np.array_equal(getattr(a, k), getattr(b, k)) for k in vars(a))
    assert (held.metadata, held.sensor_names) == (streamed.metadata, streamed.sensor_names)


def test_a_small_log_is_held() -> None:
    assert read_log(LOG, None, STREAM).stream is None  # below STREAM_FROM_BYTES


@pytest.mark.parametrize(
    "flags",
    [
        (),
        ("--sensors", "sonar1*", "--sensors", "!sonar12"),
        ("--mode", "error-aware", "--odometry-coefficient", "range_m_per_m=0.01",
         "--odometry-coefficient", "bearing_rad_per_rad=0.02"),
    ],
    ids=["standard", "sensors", "error-aware"],
)  # fmt: skip
def test_a_log_above_the_threshold_maps_as_the_held_one_byte_for_byte(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, flags: tuple[str, ...]
) -> None:
    monkeypatch.setattr(pipeline, "SYNC_CHUNK_READINGS", 700)  # many chunks, as a long log has
    held = built(tmp_path, "held", str(LOG), *flags)
    monkeypatch.setattr(csv_stream, "STREAM_FROM_BYTES", LOG.stat().st_size)
    monkeypatch.setattr(csv_stream, "PIECE_CHARS", 3_000)
    calls: list[int] = []
    read_streamed = csv_stream.read_streamed

    def counted(path: Path, gz: bool):  # type: ignore[no-untyped-def]
        log = read_streamed(path, gz)
        calls.append(log is not None and log.stream is not None)
        return log

    monkeypatch.setattr(csv_stream, "read_streamed", counted)
    assert built(tmp_path, "streamed", str(LOG), *flags) == held
    assert calls == [True]


def late_bad_field(tmp_path: Path) -> tuple[Path, int]:
    """The sample with a letter in a sonar field near its end; the line number."""
    lines = LOG.read_text().splitlines(keepends=True)
    number = len(lines) - 3
    fields = lines[number - 1].split(",")
    fields[6] = "1.2x"
    lines[number - 1] = ",".join(fields)
    bad = tmp_path / "bad.csv"
    bad.write_text("".join(lines))
    return bad, number


@pytest.mark.usefixtures("streaming")
def test_a_bad_field_late_in_a_streamed_log_is_reported_with_its_line_and_nothing_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    bad, number = late_bad_field(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    code, _, stderr = run("build", str(bad), "-o", str(out / "map.png"))
    assert code == 1
    assert stderr == f"Error: {bad}:{number}: column 'sonar2': not a number: '1.2x'\n"
    assert names(out) == set()
    monkeypatch.setattr(csv_stream, "STREAM_FROM_BYTES", 1 << 40)
    assert run("build", str(bad), "-o", str(out / "map.png"))[2] == stderr  # as when held


@pytest.mark.usefixtures("streaming")
def test_a_log_the_bulk_reader_would_not_take_is_read_held(tmp_path: Path) -> None:
    quoted = tmp_path / "quoted.csv"  # quotes: for the row reader, which holds the log
    quoted.write_text(LOG.read_text().replace("\ntime,", '\n"time",', 1))
    log = read_log(quoted, None, STREAM)
    assert log.stream is None and same_readings(log.readings, read_log(LOG).readings)


@pytest.mark.usefixtures("streaming")
def test_a_log_changed_between_passes_is_an_error(tmp_path: Path) -> None:
    copy = tmp_path / "run.csv"
    copy.write_bytes(LOG.read_bytes())
    log = read_log(copy, None, STREAM)
    assert log.stream is not None
    with open(copy, "a") as handle:
        handle.write("1e9,0,0,0" + ",1" * (len(log.sensor_names) + 3) + "\n")
    with pytest.raises(InputFileError, match="changed while gridmap read it"):
        list(log.reading_chunks(700))
