"""A map as an MCAP OccupancyGrid, decoded back with mcap-ros2-support and compared with the
image writer's output cell by cell."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from PIL import Image

from gridmap_cli.errors import GridmapError, OutputExistsError
from gridmap_cli.mapping.grid import GridSpec, OccupancyMap
from gridmap_cli.readers.text.csv_log import read_csv_log
from gridmap_cli.writers.map_mcap import occupancy_values, write_map_mcap
from tests.helpers import names, run

REPO = Path(__file__).resolve().parents[2]


def decoded_grid(path: Path) -> tuple[Any, Any, Any]:
    """(channel, message record, decoded OccupancyGrid) of the one message in ``path``."""
    with path.open("rb") as handle:
        reader = make_reader(handle, validate_crcs=True, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        found = list(reader.iter_decoded_messages())
    assert len(found) == 1
    schema, channel, message, grid = found[0]
    assert schema.name == "nav_msgs/msg/OccupancyGrid" and schema.encoding == "ros2msg"
    return channel, message, grid


def test_values_by_hand() -> None:
    prob = np.array([[np.nan, 0.0, 0.125], [0.005, 0.655, 1.0]])
    # 12.5 and 0.5 round half to even, as the raw image does
    assert occupancy_values(prob).tolist() == [[-1, 0, 12], [0, 66, 100]]


@pytest.mark.parametrize("bad", [1.5, -0.01, np.inf])
def test_probabilities_outside_0_1_are_refused_not_wrapped(bad: float, tmp_path: Path) -> None:
    """1.5 would be 150, which int8 wraps to -106; the map image's check applies here too."""
    prob = np.array([[0.5, bad]])
    with pytest.raises(ValueError, match=r"probabilities must lie in \[0, 1\]"):
        occupancy_values(prob)
    with pytest.raises(ValueError, match=r"probabilities must lie in \[0, 1\]"):
        write_map_mcap(tmp_path / "map.mcap", OccupancyMap(GridSpec(0.0, 0.0, 1.0, 2, 1), prob))
    assert names(tmp_path) == set()


def test_a_stamp_past_int32_seconds_is_an_error_not_a_traceback(tmp_path: Path) -> None:
    """ROS 2 time has int32 seconds: 2038-01-19 03:14:08 UTC does not fit."""
    spec = GridSpec(0.0, 0.0, 1.0, 1, 1)
    late = 2**31 * 1_000_000_000
    with pytest.raises(GridmapError, match=rf"stamp {late} ns does not fit a ROS 2 time"):
        write_map_mcap(tmp_path / "map.mcap", OccupancyMap(spec, np.array([[0.5]])), stamp_ns=late)
    assert names(tmp_path) == set()
    last = late - 1  # 2038-01-19 03:14:07.999999999 still fits
    write_map_mcap(tmp_path / "map.mcap", OccupancyMap(spec, np.array([[0.5]])), stamp_ns=last)
    assert decoded_grid(tmp_path / "map.mcap")[1].log_time == last


def test_a_small_map_by_hand(tmp_path: Path) -> None:
    spec = GridSpec(origin_x_m=-1.5, origin_y_m=2.0, resolution_m=0.05, width=3, height=2)
    prob = np.array([[np.nan, 0.0, 0.25], [0.5, 0.75, 1.0]])  # row 0 is the bottom
    out = write_map_mcap(tmp_path / "map.mcap", OccupancyMap(spec, prob), stamp_ns=3_000_000_007)
    channel, message, grid = decoded_grid(out)
    assert channel.topic == "/map" and channel.message_encoding == "cdr"
    assert "transient_local" in channel.metadata["offered_qos_profiles"]
    assert message.log_time == message.publish_time == 3_000_000_007
    assert grid.header.frame_id == "map"
    assert (grid.header.stamp.sec, grid.header.stamp.nanosec) == (3, 7)
    info = grid.info
    assert (info.width, info.height) == (3, 2)
    assert info.resolution == np.float32(0.05)
    assert (info.origin.position.x, info.origin.position.y, info.origin.position.z) == (
        -1.5,
        2.0,
        0.0,
    )
    q = info.origin.orientation
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)
    # row-major from the bottom row: OccupancyGrid's row 0 is at the origin
    assert list(grid.data) == [-1, 0, 25, 50, 75, 100]


def test_a_built_map_matches_the_raw_image_cell_by_cell(tmp_path: Path) -> None:
    log = str(REPO / "samples" / "corridor_loop.csv")
    code, _, err = run("build", log, "-o", str(tmp_path / "map.mcap"), "-q")
    assert code == 0, err
    code, _, err = run("build", log, "-o", str(tmp_path / "raw.pgm"), "--map-mode", "raw", "-q")
    assert code == 0, err
    _, _, grid = decoded_grid(tmp_path / "map.mcap")
    image = np.asarray(Image.open(tmp_path / "raw.pgm"))
    assert (grid.info.height, grid.info.width) == image.shape
    cells = np.asarray(grid.data, dtype=np.int16).reshape(image.shape)
    # the image's top row is the map's last row; raw images mark unknown as 255
    expected = image[::-1].astype(np.int16)
    expected[expected == 255] = -1
    assert np.array_equal(cells, expected)
    # unknown, free and occupied cells all occur, free as 0 and occupied as 100 (the only
    # values Nav2's costmap and AMCL read as free and as a wall), whatever the clamp
    assert (cells == -1).any() and (cells == 0).any() and (cells == 100).any()
    assert not ((cells > 65) & (cells < 100)).any()
    # origin as in the image's YAML
    yaml_text = (tmp_path / "raw.yaml").read_text()
    origin = f"origin: [{grid.info.origin.position.x!r}, {grid.info.origin.position.y!r}, 0.0]"
    assert origin in yaml_text
    assert grid.info.resolution == np.float32(0.05)


def test_a_built_map_is_stamped_at_the_last_reading(tmp_path: Path) -> None:
    log = REPO / "samples" / "corridor_loop.csv"
    code, _, err = run("build", str(log), "-o", str(tmp_path / "map.mcap"), "-q")
    assert code == 0, err
    _, message, grid = decoded_grid(tmp_path / "map.mcap")
    last_time = log.read_text().strip().splitlines()[-1].split(",")[0]
    assert message.log_time == round(float(last_time) * 1e9)
    # the stamp the CLI passes is the last reading's, in the header and the load time as well
    last_reading = int(read_csv_log(log).readings.stamp_ns[-1])
    assert message.log_time == message.publish_time == last_reading
    for stamp in (grid.header.stamp, grid.info.map_load_time):
        assert stamp.sec * 1_000_000_000 + stamp.nanosec == last_reading


def test_an_existing_map_needs_force(tmp_path: Path) -> None:
    spec = GridSpec(0.0, 0.0, 1.0, 1, 1)
    target = tmp_path / "map.mcap"
    target.write_bytes(b"old")
    with pytest.raises(OutputExistsError):
        write_map_mcap(target, OccupancyMap(spec, np.array([[0.5]])))
    assert target.read_bytes() == b"old"
    write_map_mcap(target, OccupancyMap(spec, np.array([[0.5]])), force=True)
    assert list(decoded_grid(target)[2].data) == [50]
    assert names(tmp_path) == {"map.mcap"}


def test_build_refuses_map_mode_for_mcap(tmp_path: Path) -> None:
    log = str(REPO / "samples" / "corridor_loop.csv")
    out = tmp_path / "map.mcap"
    code, _, err = run("build", log, "-o", str(out), "--map-mode", "scale")
    assert code == 2
    assert err.strip() == (
        "Error: --map-mode applies to map images; an MCAP map holds 0..100 and -1"
    )
    assert names(tmp_path) == set()


@pytest.mark.parametrize(("width", "height"), [(1, 1), (3, 2), (7, 5)])
def test_cells_appended_by_hand_equal_the_generic_cdr_encoder(width: int, height: int) -> None:
    from mcap_ros2._dynamic import serialize_dynamic

    from gridmap_cli.writers.map_mcap import _with_cells
    from gridmap_cli.writers.ros2_msgdefs import message_definition

    prob = np.linspace(0.0, 1.0, width * height).reshape(height, width)
    prob[0, 0] = np.nan
    encode = serialize_dynamic(
        "nav_msgs/msg/OccupancyGrid", message_definition("nav_msgs/msg/OccupancyGrid")
    )["nav_msgs/msg/OccupancyGrid"]
    message: dict[str, Any] = {
        "header": {"frame_id": "map"},
        "info": {"resolution": 0.1, "width": width, "height": height},
    }
    generic = encode({**message, "data": occupancy_values(prob, 0.65, 0.25).ravel().tolist()})
    by_hand = _with_cells(encode({**message, "data": []}), occupancy_values(prob, 0.65, 0.25))
    assert by_hand == generic
