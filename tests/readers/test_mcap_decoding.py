"""Messages and schemas that do not decode are one ``Error:`` line naming the file and the
message, never a traceback (issue 11): a ROS 2 schema that does not parse, a ROS 1 array
length claiming gigabytes, JSON nested 200,000 deep."""

from __future__ import annotations

import struct
from pathlib import Path

from tests.corpus.mcap_edit import edit_mcap
from tests.helpers import names, run
from tests.readers.mcap_helpers import Recording, S, drive, one_sonar_log, static_tf


def ros1_scan_log(path: Path) -> Path:
    """ROS 1: odometry and one three-beam LaserScan at t = 1 s (the 3rd message)."""
    with Recording(path, ros=1) as rec:
        static_tf(rec, rec.transform(0, "base_link", "laser", 0.0, 0.0, 0.0))
        drive(rec)
        rec.write(
            "/scan",
            "sensor_msgs/LaserScan",
            S,
            {
                "header": rec.header(S, "laser"),
                "angle_min": -0.1,
                "angle_max": 0.1,
                "angle_increment": 0.1,
                "range_min": 0.1,
                "range_max": 5.0,
                "ranges": [1.0, 1.0, 1.0],
                "intensities": [],
            },
        )
    return path


def fails(tmp_path: Path, log: Path) -> str:
    before = names(tmp_path)
    code, out, err = run("build", str(log), "-o", str(tmp_path / "m.png"))
    assert (code, out) == (1, "")
    assert err.count("\n") == 1 and err.startswith(f"Error: {log}: "), err
    assert names(tmp_path) == before
    return err


def test_a_ros1_array_length_claiming_gigabytes_names_the_message(tmp_path: Path) -> None:
    good = ros1_scan_log(tmp_path / "good.mcap")

    def claim(topic: str, data: bytes) -> bytes:
        if topic != "/scan":
            return data
        frame_len = struct.unpack_from("<I", data, 12)[0]
        at = 16 + frame_len + 28  # header, then seven float32 before ranges
        assert struct.unpack_from("<I", data, at)[0] == 3
        return data[:at] + struct.pack("<I", 0x7FFFFFFF) + data[at + 4 :]

    bad = edit_mcap(good, tmp_path / "bad.mcap", claim)
    good.unlink()
    err = fails(tmp_path, bad)
    assert (
        "message 1 of /scan (sensor_msgs/LaserScan, log time 1.000000000 s) does not decode" in err
    )


def test_a_ros2_schema_that_does_not_parse_names_the_topic(tmp_path: Path) -> None:
    good = one_sonar_log(tmp_path / "good.mcap")
    bad = edit_mcap(
        good,
        tmp_path / "bad.mcap",
        schema=lambda name, data: b"float32[ range\n(((" if name.endswith("Range") else data,
    )
    good.unlink()
    err = fails(tmp_path, bad)
    assert "/sonar: the schema of sensor_msgs/Range does not parse (InvalidResourceName" in err


def test_a_ros1_schema_that_does_not_parse_names_the_topic(tmp_path: Path) -> None:
    good = ros1_scan_log(tmp_path / "good.mcap")
    bad = edit_mcap(
        good,
        tmp_path / "bad.mcap",
        schema=lambda name, data: b"float32[ ranges" if name.endswith("LaserScan") else data,
    )
    good.unlink()
    assert "/scan: the schema of sensor_msgs/LaserScan does not parse" in fails(tmp_path, bad)


def test_json_nested_200000_deep_is_one_line(tmp_path: Path) -> None:
    csv = Path(__file__).resolve().parents[2] / "samples" / "corridor_loop.csv"
    good = tmp_path / "good.mcap"
    assert run("convert", str(csv), str(good))[0] == 0
    seen = [0]

    def nest(topic: str, data: bytes) -> bytes:
        seen[0] += 1
        return b"[" * 200_000 + b"]" * 200_000 if seen[0] == 50 else data

    bad = edit_mcap(good, tmp_path / "bad.mcap", nest)
    good.unlink()
    err = fails(tmp_path, bad)
    assert " of /range (gridmap.RangeReading" in err and "RecursionError" in err
