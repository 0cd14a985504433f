"""`gridmap convert` and `gridmap simulate -o run.mcap`: formats chosen by name or flag, what a
format cannot hold refused with one error line, nothing written on error.

MCAP files are checked here only through the ``mcap`` library (counts, encodings); their
content is checked message by message in tests/writers/test_mcap_log.py.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from gridmap_cli.readers import format_names, resolve_format
from gridmap_cli.readers.text.aria_log import read_aria_log
from gridmap_cli.readers.text.csv_log import read_csv_log
from tests.helpers import names, run
from tests.writers.test_mcap_log import ros2_messages

REPO = Path(__file__).resolve().parent.parent
SAMPLES = REPO / "samples"


def topic_counts(path: Path) -> tuple[str, dict[str, int]]:
    """(profile, message count per topic) from the file's summary."""
    with path.open("rb") as handle:
        reader = make_reader(handle, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        topic = {c.id: c.topic for c in summary.channels.values()}
        counts = {topic[k]: v for k, v in summary.statistics.channel_message_counts.items()}
        return reader.get_header().profile, counts


@pytest.mark.parametrize(
    ("encoding", "sample"), [(None, "corridor_loop.mcap"), ("ros2", "corridor_loop_ros2.mcap")]
)
def test_csv_to_mcap_gives_the_sample_bytes(
    encoding: str | None, sample: str, tmp_path: Path
) -> None:
    """The sample CSV converted is the MCAP sample `simulate` wrote, byte for byte."""
    out = tmp_path / "run.mcap"
    extra = ["--encoding", encoding] if encoding else []
    code, stdout, err = run("convert", str(SAMPLES / "corridor_loop.csv"), str(out), *extra)
    assert code == 0, err
    assert stdout == ""
    what = f"mcap ({encoding or 'json'})"
    assert err == (f"gridmap: csv -> {what}: 1,468 poses, 23,488 readings, ground truth -> {out}\n")
    # the CSV's layout key is not carried into other formats, so the bytes are simulate's
    assert out.read_bytes() == (SAMPLES / sample).read_bytes()


def test_mcap_counts() -> None:
    profile, counts = topic_counts(SAMPLES / "corridor_loop.mcap")
    assert profile == ""
    assert counts == {"/sensors": 16, "/odom": 1468, "/ground_truth": 1468, "/range": 23488}
    profile, counts = topic_counts(SAMPLES / "corridor_loop_ros2.mcap")
    assert profile == "ros2"
    assert counts == {
        "/tf_static": 1,
        "/odom": 1468,
        "/tf": 1468,
        "/ground_truth": 1468,
        "/sonar": 23488,
    }


def test_csv_to_aria_and_back(tmp_path: Path) -> None:
    aria = tmp_path / "run.2d"
    code, _, err = run("convert", str(SAMPLES / "corridor_loop.csv"), str(aria), "-q")
    assert code == 0 and err == ""
    assert aria.read_bytes() == (SAMPLES / "corridor_loop.2d").read_bytes()
    back = tmp_path / "back.csv"
    code, _, err = run("convert", str(aria), str(back), "-q")
    assert code == 0, err
    original, again = read_csv_log(SAMPLES / "corridor_loop.csv"), read_csv_log(back)
    for a, b in ((original.poses, again.poses), (original.truth, again.truth)):
        assert a is not None and b is not None
        assert (a.stamp_ns == b.stamp_ns).all() and (a.x_m == b.x_m).all()
        assert (a.theta_rad == b.theta_rad).all()
    assert (original.readings.range_m == again.readings.range_m).all()
    assert read_aria_log(aria).sensor_names == original.sensor_names


def test_format_flag_overrides_the_name(tmp_path: Path) -> None:
    out = tmp_path / "run.log"
    code, _, err = run(
        "convert", str(SAMPLES / "corridor_loop.csv"), str(out), "--to", "mcap", "-q"
    )
    assert code == 0, err
    assert out.read_bytes()[:8] == b"\x89MCAP0\r\n"


def test_simulate_writes_mcap(tmp_path: Path) -> None:
    world = SAMPLES / "worlds" / "corridor_loop.yaml"
    path = SAMPLES / "paths" / "corridor_loop.yaml"
    out = tmp_path / "sim.out"
    code, _, err = run(
        "simulate", str(world), str(path), "-o", str(out), "--to", "mcap",
        "--encoding", "ros2", "--duration", "2", "--quiet",
    )  # fmt: skip
    assert code == 0, err
    profile, counts = topic_counts(out)
    assert profile == "ros2"
    # 2 s at 10 Hz: 20 stamps (0.0 .. 1.9), 16 sonars each
    assert counts["/odom"] == counts["/tf"] == 20 and counts["/sonar"] == 20 * 16


def test_mcap_input_goes_through_the_readers_registry(tmp_path: Path) -> None:
    """MCAP input is read through the readers registry, like every other format."""
    assert "mcap" in format_names()
    out = tmp_path / "back.csv"
    code, _, err = run("convert", str(SAMPLES / "corridor_loop.mcap"), str(out), "-q")
    assert code == 0, err
    assert read_csv_log(out).readings.range_m.tolist() == (
        read_csv_log(SAMPLES / "corridor_loop.csv").readings.range_m.tolist()
    )


@pytest.mark.parametrize(
    ("out_name", "extra"),
    [("back.csv", []), ("back.2d", []), ("back.mcap", []), ("ros2.mcap", ["--encoding", "ros2"])],
)
def test_an_infinite_range_reads_back_as_no_echo_in_every_format(
    out_name: str, extra: list[str], tmp_path: Path
) -> None:
    """A CSV's `inf` (no echo) is written as the sensor's maximum range wherever geometry is
    known, and as `inf` again in CSV; either reads back as a range at or above the maximum."""
    log = tmp_path / "inf.csv"
    log.write_text(
        "# robot: p3at\ntime,x,y,theta,sonar0,sonar1\n0.0,0,0,0,inf,1.5\n0.1,0.01,0,0,2.0,inf\n"
    )
    out = tmp_path / out_name
    code, _, err = run("convert", str(log), str(out), *extra, "-q")
    assert code == 0, err
    assert "Warning" not in err
    back = resolve_format(out).read(out)
    got = [
        (int(t), back.sensor_names[k], float(r))
        for t, k, r in zip(
            back.readings.stamp_ns, back.readings.sensor, back.readings.range_m, strict=True
        )
    ]
    no_echo = math.inf if out.suffix == ".csv" else 4.335  # the p3at sonar's maximum range
    assert got == [
        (0, "sonar0", no_echo),
        (0, "sonar1", 1.5),
        (100_000_000, "sonar0", 2.0),
        (100_000_000, "sonar1", no_echo),
    ]
    if out.suffix == ".mcap" and extra:  # sensor_msgs/Range: no echo is range == max_range
        sonar = [m for t, _, m in ros2_messages(out.read_bytes()) if t == "/sonar"]
        top = np.float32(4.335)
        assert [(m.range, m.max_range) for m in sonar] == [
            (top, top),
            (1.5, top),
            (2.0, top),
            (top, top),
        ]


def write_odd_robot_log(tmp_path: Path) -> Path:
    """A CSV whose one sensor, 'front', is described by a robot YAML beside it."""
    (tmp_path / "bot.yaml").write_text(
        "gridmap-robot: 1\nname: bot\nsensors:\n"
        "  - {name: front, x_m: 0.1, y_m: 0.0, yaw_deg: 0, beam_width_deg: 20, max_range_m: 3}\n"
    )
    log = tmp_path / "odd.csv"
    log.write_text("# robot: bot.yaml\ntime,x,y,theta,front\n0.0,0,0,0,1.5\n0.1,0.1,0,0,3.0\n")
    return log


def test_geometry_comes_from_the_logs_robot(tmp_path: Path) -> None:
    log = write_odd_robot_log(tmp_path)
    out = tmp_path / "odd.mcap"
    code, _, err = run("convert", str(log), str(out), "-q")
    assert code == 0, err
    assert topic_counts(out)[1] == {"/sensors": 1, "/odom": 2, "/range": 2}


@pytest.mark.parametrize(
    "case",
    [
        "exists",
        "unknown suffix",
        "encoding for csv",
        "missing input",
        "aria cannot hold",
        "no robot",
    ],
)
def test_errors_are_one_line_and_leave_nothing(case: str, tmp_path: Path) -> None:
    sample = str(SAMPLES / "corridor_loop.csv")
    work = tmp_path / "work"
    work.mkdir()
    expected_code = 1
    if case == "exists":
        (work / "run.mcap").write_bytes(b"old")
        args = [sample, str(work / "run.mcap")]
        message = f"{work / 'run.mcap'} exists (use --force to overwrite)"
    elif case == "unknown suffix":
        args = [sample, str(work / "run.bag")]
        expected_code = 2
        message = (
            f"{work / 'run.bag'}: cannot tell the log format from the name; end it in one of "
            "csv (.csv), aria (.2d), mcap (.mcap) or give --to"
        )
    elif case == "encoding for csv":
        args = [sample, str(work / "run.csv"), "--encoding", "ros2"]
        expected_code = 2
        message = "--encoding applies to MCAP output only, not csv"
    elif case == "missing input":
        args = [str(tmp_path / "nope.csv"), str(work / "run.mcap")]
        message = f"{tmp_path / 'nope.csv'}: no such file"
    elif case == "aria cannot hold":
        log = write_odd_robot_log(tmp_path)
        args = [str(log), str(work / "odd.2d")]
        message = (
            f"{work / 'odd.2d'}: cannot write as aria: the ARIA format cannot hold sensor "
            "'front': sonar units are sonar0, sonar1, ... in order and laser beams "
            "laser<N>_0, laser<N>_1, ..."
        )
    else:
        log = tmp_path / "plain.csv"
        log.write_text("time,x,y,theta,front\n0.0,0,0,0,1.5\n")
        args = [str(log), str(work / "plain.mcap")]
        message = (
            f"{log}: the log does not describe sensor 'front'; give --robot "
            "(a preset name, a robot YAML file or an ARIA .p file)"
        )
    before = names(work)
    code, stdout, err = run("convert", *args)
    assert code == expected_code
    assert stdout == ""
    assert err == f"Error: {message}\n"
    assert names(work) == before
