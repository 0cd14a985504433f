"""The CSV reader: what it reads, and the exact error a user sees for each kind of bad input."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gridmap_cli.errors import InputFileError
from gridmap_cli.readers.text import csv_log
from gridmap_cli.readers.text.csv_log import read_csv_log, seconds_to_ns, sniff
from gridmap_cli.records import RangeLog
from tests.helpers import run

GOOD = """\
# gridmap-csv: 1
# robot: p3at
time,x,y,theta,sonar0,sonar1,true_x,true_y,true_theta
0.0,0,0,0,1.5,,10,20,0.5
0.1,0.04,0.0,0.01,nan,4.335,10.04,20,0.51
0.2,0.08,0.001,0.02,2.25,3.0,10.08,20.001,0.52
"""


def write(tmp_path: Path, text: str, name: str = "log.csv") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_reads_poses_readings_truth_and_metadata(tmp_path: Path) -> None:
    log = read_csv_log(write(tmp_path, GOOD))
    assert log.metadata == {"gridmap-csv": "1", "robot": "p3at"}
    assert log.sensor_names == ("sonar0", "sonar1")
    assert list(log.poses.stamp_ns) == [0, 100_000_000, 200_000_000]
    assert list(log.poses.x_m) == [0.0, 0.04, 0.08]
    # empty and nan cells are no reading at all; order is by stamp, then sensor
    assert list(log.readings.stamp_ns) == [0, 100_000_000, 200_000_000, 200_000_000]
    assert list(log.readings.sensor) == [0, 1, 0, 1]
    assert list(log.readings.range_m) == [1.5, 4.335, 2.25, 3.0]
    assert log.truth is not None and list(log.truth.theta_rad) == [0.5, 0.51, 0.52]


def test_reads_from_a_text_handle_and_a_bom() -> None:
    log = read_csv_log(io.StringIO("\ufefftime,x,y,theta,s\n1,0,0,0,2\n"), "mem")
    assert log.source == "mem" and log.truth is None and list(log.readings.range_m) == [2.0]


def test_sniff() -> None:
    assert sniff(GOOD.encode())
    assert sniff(b"time,x,y,theta\n")
    assert not sniff(b"LaserOdometryLog\n")
    assert not sniff(b"\x89MCAP0\r\n")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("x,y,theta,s0\n0,0,0,1\n", "log.csv:1: missing required column 'time'"),
        ("time,x,theta\n0,0,0\n", "log.csv:1: missing required column 'y' (header has"),
        ("time,theta\n0,0\n", "log.csv:1: missing required columns 'x', 'y'"),
        (
            "time,x,y,theta,s0\n0,0,0,0,1\n0.1,0,zero,0,1\n",
            "log.csv:3: column 'y': not a number: 'zero'",
        ),
        (
            "time,x,y,theta,s0\n0,0,0,0,1\n0.1,0,0,0,far\n",
            "log.csv:3: column 's0': not a number: 'far'",
        ),
        (
            "time,x,y,theta,s0\n1,0,0,0,1\n0.5,0,0,0,1\n",
            "log.csv:3: column 'time': time goes backwards: 0.5 s after 1 s",
        ),
        (
            "time,x,y,theta,s0\n1,0,0,0,1\n1.0,0,0,0,1\n",
            "log.csv:3: column 'time': time repeats",
        ),
        (
            "time,x,y,theta,s0\n0,nan,0,0,1\n",
            "log.csv:2: column 'x': pose must be finite, got 'nan'",
        ),
        ("time,x,y,theta,s0\n0,0,inf,0,1\n", "log.csv:2: column 'y': pose must be finite"),
        (
            "time,x,y,theta,s0,s1\n0,0,0,0,1,1\n0.1,0,0,0,1\n",
            "log.csv:3: expected 6 fields, found 5 (truncated file?)",
        ),
        ("time,x,y,theta,s0\n0,0,0,0,-1\n", "log.csv:2: column 's0': negative range -1 m"),
        ("# robot: p3at\n\n", "log.csv: no header row"),
        ("time,x,y,theta,s0\n", "log.csv:1: no data rows after the header"),
        ("time,x,y,theta,s0,true_x\n0,0,0,0,1,2\n", "log.csv:1: ground truth needs all of"),
        ("time,x,y,theta,s0,s0\n0,0,0,0,1,2\n", "log.csv:1: column 's0' appears twice"),
        ("time,x,y,theta,s0\nabc,0,0,0,1\n", "log.csv:2: column 'time': not a number: 'abc'"),
    ],
)
def test_bad_input_names_file_line_and_column(tmp_path: Path, text: str, message: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(InputFileError) as info:
        read_csv_log(path)
    assert str(info.value).startswith(str(tmp_path / message.split(":")[0]) + ":")
    assert message.split(":", 1)[1] in str(info.value)


def test_missing_file_and_binary_file(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="cannot read"):
        read_csv_log(tmp_path / "absent.csv")
    path = tmp_path / "bin.csv"
    path.write_bytes(b"time,x,y,theta\n\xff\xfe\x00\n")
    with pytest.raises(InputFileError, match="not UTF-8"):
        read_csv_log(path)


def test_truncated_last_line_is_reported(tmp_path: Path) -> None:
    lines = GOOD.splitlines()
    text = "\n".join(lines) + "\n" + "0.3,0.12,0.0"  # cut off mid-row, no newline
    with pytest.raises(InputFileError, match=r"log.csv:7: expected 9 fields, found 3"):
        read_csv_log(write(tmp_path, text))


@given(st.integers(min_value=-(10**18), max_value=10**18))
def test_seconds_text_round_trips_nanoseconds(ns: int) -> None:
    sign = "-" if ns < 0 else ""
    whole, frac = divmod(abs(ns), 10**9)
    assert seconds_to_ns(f"{sign}{whole}.{frac:09d}") == ns


def test_seconds_to_ns_forms() -> None:
    assert seconds_to_ns("1700000000.123456789") == 1_700_000_000_123_456_789
    assert seconds_to_ns("12") == 12 * 10**9
    assert seconds_to_ns(".5") == 500_000_000
    assert seconds_to_ns("1e-3") == 1_000_000
    for bad in ("", "nan", "inf", "1.2.3", "--1"):
        with pytest.raises(ValueError, match=r"^not a number: "):
            seconds_to_ns(bad)
    # more than nine decimals round through float, keeping the sign once (it was negated twice)
    assert seconds_to_ns("-0.1234567891") == -123_456_789
    assert seconds_to_ns("0.1234567891") == 123_456_789


@pytest.mark.parametrize("huge", ["1e300", "-1e300", "1e10", "9" * 40, "1" + "0" * 12 + ".5"])
def test_seconds_no_int64_stamp_holds_are_refused_by_name(huge: str) -> None:
    with pytest.raises(ValueError, match="beyond what a nanosecond stamp holds"):
        seconds_to_ns(huge)
    assert seconds_to_ns("9e9") == 9 * 10**18  # 285 years: still a stamp


def test_a_csv_time_beyond_any_stamp_is_one_line(tmp_path: Path) -> None:
    log = tmp_path / "run.csv"
    log.write_text("time,x,y,theta\n0,0,0,0\n1e300,1,0,0\n")
    out = tmp_path / "m.png"
    code, stdout, stderr = run("build", str(log), "-o", str(out))
    assert (code, stdout) == (1, "") and not out.exists()
    assert stderr == (
        f"Error: {log}:3: column 'time': '1e300' s is beyond what a nanosecond stamp holds "
        "(about 292 years from zero)\n"
    )


def test_empty_sensor_set_is_allowed() -> None:
    log = read_csv_log(io.StringIO("time,x,y,theta\n0,0,0,0\n1,1,0,0\n"))
    assert len(log.readings) == 0 and log.sensor_names == ()
    assert np.array_equal(log.poses.x_m, [0.0, 1.0])


def _same_log(text: str) -> RangeLog | None:
    """The bulk parse of ``text``, checked equal to the row-by-row parse when it gives one."""
    bulk = csv_log._read_bulk(text, "x.csv")
    rows = csv_log._read_rows(io.StringIO(text), "x.csv")
    if bulk is not None:
        for a, b in ((bulk.readings, rows.readings), (bulk.poses, rows.poses)):
            for name in vars(a):
                assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert (bulk.truth is None) == (rows.truth is None)
        if bulk.truth is not None and rows.truth is not None:
            assert np.array_equal(bulk.truth.x_m, rows.truth.x_m)
        assert (bulk.sensor_names, bulk.metadata) == (rows.sensor_names, rows.metadata)
    return bulk


@pytest.mark.parametrize(
    "body",
    [
        "0.0,1,2,0.5,,\n0.1,1,2,0.5,nan,3\n",  # empty and nan: no reading
        "0.0,1,2,0.5,,\r\n\r\n0.1,1,2,0.5,inf,NaN\r\n",  # CRLF, a blank line, no echo
        "1700000000.123456789,1e-3,-2,0.5,4.335,0.7\n1700000000.2,1,2,3,,",  # epoch ns, no EOL
        " 0.0 , 1 ,2,0.5, 1.5 ,0.2\n",  # spaces around numbers
    ],
)
def test_bulk_parse_equals_the_row_reader(body: str) -> None:
    text = "# robot: p3at\ntime,x,y,theta,s0,s1\n" + body
    assert _same_log(text) is not None


@pytest.mark.parametrize(
    "body",
    [
        "0.0,1,2,0.5,x,1\n",  # not a number
        "0.0,1,2,0.5,-1,1\n",  # negative range
        "0.1,1,2,0.5,1,1\n0.1,1,2,0.5,1,1\n",  # time repeats
        "0.0,1,nan,0.5,1,1\n",  # pose not finite
        "0.0,1,2,0.5,1\n",  # a field short
        '0.0,1,2,0.5,"1",1\n',  # quotes: the csv module's business
    ],
)
def test_anything_odd_is_left_to_the_row_reader_and_its_errors(body: str) -> None:
    text = "time,x,y,theta,s0,s1\n" + body
    assert csv_log._read_bulk(text, "x.csv") is None
    if '"' in body:
        return
    with pytest.raises(InputFileError, match=r"x\.csv:[23]: "):
        read_csv_log(io.StringIO(text), "x.csv")


@given(
    st.lists(
        st.lists(
            st.one_of(st.just(""), st.just("nan"), st.floats(0, 50).map(repr)),
            min_size=3,
            max_size=3,
        ),
        min_size=1,
        max_size=20,
    )
)
def test_bulk_parse_equals_the_row_reader_on_any_table(cells: list[list[str]]) -> None:
    lines = [f"{i / 10!r},{i},{-i},0.25,{','.join(row)}" for i, row in enumerate(cells)]
    text = "time,x,y,theta,a,b,c\n" + "\n".join(lines) + "\n"
    assert _same_log(text) is not None


def test_a_carriage_return_inside_the_header_line_is_a_gridmap_error() -> None:
    # found by the fuzz test: the csv module raises its own error on a lone \r in a field
    text = "\x00\r# gridmap-csv: 1\ntime,x,y,theta,sonar0\n0.0,0.0,0.0,0.0,1.5\n"
    with pytest.raises(InputFileError, match=r"^x\.csv:1: unreadable header row"):
        read_csv_log(io.StringIO(text), name="x.csv")
