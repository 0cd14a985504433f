"""ROS 1 bags, rosbag2 folders and several recordings read as one.

Bags are made from ``samples/corridor_loop_ros2.mcap`` (tests/readers/bag_helpers.py), so the
same run exists as MCAP, ROS 1 bag, sqlite3 and MCAP rosbag2: all must give the same canonical
stream and the same map bytes, whole or split by topic into several files.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin

from gridmap_cli.errors import InputFileError, UsageError
from gridmap_cli.readers import read_log, read_logs, recording_sources, resolve_format
from gridmap_cli.records import RangeLog
from tests.helpers import names, run
from tests.readers.bag_helpers import write_bag, write_rosbag2

SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "corridor_loop_ros2.mcap"
ODOMETRY_TOPICS = ("/odom", "/tf", "/tf_static", "/ground_truth")


def same_stream(a: RangeLog, b: RangeLog) -> None:
    assert a.sensor_names == b.sensor_names
    assert a.sensors == b.sensors
    for track_a, track_b in ((a.poses, b.poses), (a.truth, b.truth)):
        assert track_a is not None and track_b is not None
        assert np.array_equal(track_a.stamp_ns, track_b.stamp_ns)
        assert np.array_equal(track_a.x_m, track_b.x_m)
        assert np.array_equal(track_a.theta_rad, track_b.theta_rad)
    assert np.array_equal(a.readings.stamp_ns, b.readings.stamp_ns)
    assert np.array_equal(a.readings.sensor, b.readings.sensor)
    assert np.array_equal(a.readings.range_m, b.readings.range_m)


Make = Callable[..., Path]


@pytest.fixture(scope="module")
def container(tmp_path_factory: pytest.TempPathFactory) -> Make:
    """``container(kind, name, keep=None)``: the sample run (only the ``keep`` topics, if given)
    as a ``kind`` recording; made once per module (read-only for the tests: converting the
    28,000 messages takes a second)."""
    folder = tmp_path_factory.mktemp("recordings")
    made: dict[tuple[str, str, tuple[str, ...] | None], Path] = {}

    def make(kind: str, name: str, keep: tuple[str, ...] | None = None) -> Path:
        key = (kind, name, keep)
        if key not in made:
            target = folder / f"{kind}-{name}"

            def wanted(topic: str) -> bool:
                return keep is None or topic in keep

            if kind == "bag":
                made[key] = write_bag(SAMPLE, target.with_suffix(".bag"), wanted)
            elif kind == "rosbag2-sqlite3":
                made[key] = write_rosbag2(SAMPLE, target, wanted)
            else:
                made[key] = write_rosbag2(SAMPLE, target, wanted, StoragePlugin.MCAP)
        return made[key]

    return make


def build_bytes(tmp_path: Path, name: str, *logs: Path) -> tuple[bytes, bytes]:
    out = tmp_path / name / "map.png"
    out.parent.mkdir()
    code, _, err = run("build", *map(str, logs), "-o", str(out), "--quiet")
    assert code == 0, err
    return out.read_bytes(), out.with_suffix(".yaml").read_bytes()


@pytest.mark.parametrize("kind", ["bag", "rosbag2-sqlite3", "rosbag2-mcap"])
def test_a_recording_reads_alike_in_every_container(
    tmp_path: Path, kind: str, container: Make
) -> None:
    recording = container(kind, "run")
    expected_format = "bag" if kind == "bag" else "rosbag2"
    assert resolve_format(recording).name == expected_format
    same_stream(read_logs([recording]), read_log(SAMPLE))


@pytest.mark.parametrize(
    ("odometry_kind", "sonar_kind"),
    [("bag", "bag"), ("rosbag2-sqlite3", "rosbag2-sqlite3"), ("bag", "rosbag2-mcap")],
)
def test_a_recording_split_by_topic_builds_the_same_map_as_the_whole(
    tmp_path: Path, odometry_kind: str, sonar_kind: str, container: Make
) -> None:
    odometry = container(odometry_kind, "odometry", ODOMETRY_TOPICS)
    sonar = container(sonar_kind, "sonar", ("/sonar",))
    assert [s.path for s in recording_sources([odometry, sonar])][:1] == [odometry]
    same_stream(read_logs([sonar, odometry]), read_log(SAMPLE))  # in any order
    assert build_bytes(tmp_path, "split", odometry, sonar) == build_bytes(tmp_path, "whole", SAMPLE)


def test_a_rosbag2_folder_is_found_from_its_metadata_or_database_file(
    tmp_path: Path, container: Make
) -> None:
    folder = container("rosbag2-sqlite3", "run")
    whole = read_logs([folder])
    for given in (folder / "metadata.yaml", folder / f"{folder.name}.db3"):
        assert resolve_format(given).name == "rosbag2"
        same_stream(read_logs([given]), whole)


def test_split_recordings_that_disagree_on_a_topic_type_are_refused(
    tmp_path: Path, container: Make
) -> None:
    sonar = container("bag", "sonar", ("/sonar",))
    odometry = container("bag", "odom-only", ("/odom",))
    # the same topic name with another type: the odometry recorded as /sonar
    clash = write_rosbag2(
        SAMPLE, tmp_path / "clash", lambda t: t == "/odom", rename={"/odom": "/sonar"}
    )
    with pytest.raises(InputFileError) as err:
        read_logs([odometry, sonar, clash])
    assert str(err.value) == (
        f"{clash}: topic /sonar is nav_msgs/Odometry here but sensor_msgs/Range in {sonar}: "
        "the recordings do not belong together"
    )


def test_several_logs_must_all_be_ros_recordings(tmp_path: Path) -> None:
    csv = Path(__file__).resolve().parents[2] / "samples" / "corridor_loop.csv"
    with pytest.raises(UsageError, match="several logs are read as one only when all are ROS"):
        read_logs([SAMPLE, csv])
    out = tmp_path / "map.png"
    code, _, err = run("build", str(SAMPLE), str(csv), "-o", str(out))
    assert code == 2
    assert err.strip() == (
        f"Error: {csv}: several logs are read as one only when all are ROS recordings (MCAP, "
        "bag, rosbag2 folder); this is a csv log; gridmap batch maps each log on its own, and "
        "build --fuse maps several runs through one place into one map"
    )
    assert names(tmp_path) == set()


def test_a_truncated_bag_is_one_error_line_naming_it(tmp_path: Path, container: Make) -> None:
    whole = container("bag", "run")
    cut = tmp_path / "cut.bag"
    cut.write_bytes(whole.read_bytes()[: whole.stat().st_size // 2])
    out = tmp_path / "maps" / "map.png"
    out.parent.mkdir()
    code, _, err = run("build", str(cut), "-o", str(out))
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"Error: {cut}: byte "), err
    assert "truncated or damaged ROS 1 bag: record data claims" in lines[0]
    assert names(out.parent) == set()


def test_a_bag_that_is_not_a_bag_is_one_error_line(tmp_path: Path) -> None:
    fake = tmp_path / "fake.bag"
    fake.write_text("#ROSBAG V2.0\nnot really\n")
    code, _, err = run("build", str(fake), "-o", str(tmp_path / "map.png"))
    assert code == 1
    assert err.startswith(f"Error: {fake}: byte 13: truncated or damaged ROS 1 bag: record header")
    assert err.count("\n") == 1
    assert names(tmp_path) == {"fake.bag"}


def test_a_folder_that_is_no_rosbag2_is_refused(tmp_path: Path) -> None:
    folder = tmp_path / "logs"
    folder.mkdir()
    code, _, err = run("build", str(folder), "-o", str(tmp_path / "map.png"))
    assert (code, err.strip()) == (
        1,
        f"Error: {folder}: a directory, but not a rosbag2 folder (no metadata.yaml in it); "
        f"gridmap batch {folder} -o OUTDIR maps each log in a folder",
    )
    assert names(tmp_path) == {"logs"}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "rosbag2_bagfile_information: [",
            ":1: not a rosbag2 metadata file: not valid YAML: while parsing a flow node",
        ),
        ("something_else: 1\n", "not a rosbag2 metadata file (KeyError"),
        (
            "rosbag2_bagfile_information: {storage_identifier: leveldb}\n",
            "unknown rosbag2 storage 'leveldb' (gridmap reads sqlite3 and mcap)",
        ),
        (
            "rosbag2_bagfile_information:\n  storage_identifier: mcap\n"
            "  relative_file_paths: [a.mcap]\n",
            "names MCAP files that are not in the folder: a.mcap",
        ),
    ],
)
def test_a_broken_rosbag2_metadata_file_is_named(tmp_path: Path, text: str, message: str) -> None:
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "metadata.yaml").write_text(text)
    with pytest.raises(InputFileError) as err:
        read_logs([folder])
    where = f"{folder / 'metadata.yaml'}" + ("" if message.startswith(":1:") else ": ")
    assert str(err.value).startswith(where + message)


def test_inspect_describes_a_bag_like_its_mcap(tmp_path: Path, container: Make) -> None:
    bag = container("bag", "run")
    code, out, err = run("inspect", str(bag), "--json")
    assert code == 0, err
    code, mcap_out, _ = run("inspect", str(SAMPLE), "--json")
    from_bag, from_mcap = json.loads(out), json.loads(mcap_out)
    assert from_bag["format"] == "bag"
    assert from_mcap["log"].pop("metadata")["robot"] == "p3at"  # gridmap's own MCAP record
    assert from_bag["log"].pop("metadata") == {}
    assert from_bag["log"] == from_mcap["log"]
    assert from_mcap["build"].pop("robot")["name"] == "p3at"  # named by that record
    assert from_bag["build"].pop("robot") is None
    assert from_bag["build"] == from_mcap["build"]
    topics = {c["topic"]: c["messages"] for c in from_bag["mcap"]["channels"]}
    assert topics == {c["topic"]: c["messages"] for c in from_mcap["mcap"]["channels"]}
