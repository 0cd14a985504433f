"""Writer for a finished map as an MCAP file: one ``nav_msgs/msg/OccupancyGrid`` on ``/map``.

ROS 2 CDR with the ``ros2`` profile, so Foxglove and RViz (through ``ros2 bag play``) show it.
Cell values are what ``map_server``'s loader gives for a raw map and what its saver inverts:
round(100 p) (half to even, as the raw image) for a probability p, and -1 for a cell no reading
touched. ``data`` is row-major with row 0 at ``info.origin`` (the bottom of the map, the
image's last row), as OccupancyGrid defines it.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt
from mcap_ros2._dynamic import serialize_dynamic

from gridmap_cli.atomic import atomic_write
from gridmap_cli.mapping.grid import OccupancyMap
from gridmap_cli.readers.ros.frames import IDENTITY_ROTATION
from gridmap_cli.writers import check_output
from gridmap_cli.writers.map_image import occupancy_percent
from gridmap_cli.writers.mcap_log import (
    LIBRARY,
    mcap_writer,
    qos_profiles_yaml,
    ros_quaternion,
    ros_time,
)
from gridmap_cli.writers.ros2_msgdefs import message_definition

MAP_SCHEMA = "nav_msgs/msg/OccupancyGrid"
MAP_TOPIC = "/map"
MAP_FRAME = "map"


def occupancy_values(
    prob: npt.NDArray[np.float64],
    occupied_thresh: float | None = None,
    free_thresh: float | None = None,
) -> npt.NDArray[np.int8]:
    """OccupancyGrid cell values of a probability map, same shape (height, width), row 0 bottom:
    round(100 p) with halves to even, -1 for NaN (unknown); with the thresholds, 100 and 0 for
    the cells the map calls occupied and free, as a raw map holds them. ``ValueError`` as
    :func:`~gridmap_cli.writers.map_image.occupancy_percent` raises it."""
    percent, unknown = occupancy_percent(prob, occupied_thresh, free_thresh)
    values = percent.view(np.int8)  # 0..100: the same bytes
    values[unknown] = -1
    return values


def _with_cells(empty: bytes, cells: npt.NDArray[np.int8]) -> bytes:
    """The CDR of an OccupancyGrid whose ``data`` was encoded empty, with the cells filled in.

    ``data`` is the message's last field: a uint32 count then one byte per cell, so the count 0
    at the end of ``empty`` is replaced by the real one and the cells appended. The generic
    encoder would take seconds for a few million cells, one Python object each.
    """
    if empty[-4:] != b"\0\0\0\0":
        raise AssertionError("an OccupancyGrid encoded with empty data must end in a zero count")
    flat = cells.ravel()
    return empty[:-4] + struct.pack("<I", flat.size) + flat.tobytes()


def write_map_mcap(
    path: Path,
    omap: OccupancyMap,
    *,
    stamp_ns: int = 0,
    force: bool = False,
    layers: Sequence[tuple[str, npt.NDArray[np.int8]]] = (),
    thresholds: tuple[float, float] | None = None,
) -> Path:
    """Write ``omap`` as an MCAP holding one OccupancyGrid stamped ``stamp_ns`` (integer ns).

    ``info.origin`` is the lower-left corner of cell (0, 0) with identity orientation;
    ``info.resolution`` is the cell size (float32 in the message). ``thresholds`` (occupied,
    free): the cells the map calls occupied are 100 and free 0, as Nav2's costmap and AMCL read
    only those as walls and free space. ``layers``: more grids of the map's geometry, each
    (topic, cell values of shape ``omap.spec.shape``, row 0 at the bottom), one message each on
    its own topic. Written atomically.
    """
    check_output(path, force)
    spec = omap.spec
    if omap.prob.shape != spec.shape:
        raise ValueError(f"probability array of shape {omap.prob.shape} for a grid of {spec.shape}")
    stamp = ros_time(int(stamp_ns))
    message = {
        "header": {"stamp": stamp, "frame_id": MAP_FRAME},
        "info": {
            "map_load_time": stamp,
            "resolution": float(spec.resolution_m),
            "width": spec.width,
            "height": spec.height,
            "origin": {
                "position": {"x": float(spec.origin_x_m), "y": float(spec.origin_y_m), "z": 0.0},
                "orientation": ros_quaternion(IDENTITY_ROTATION),
            },
        },
        "data": [],
    }
    text = message_definition(MAP_SCHEMA)
    empty = serialize_dynamic(MAP_SCHEMA, text)[MAP_SCHEMA](message)
    grids = [(MAP_TOPIC, occupancy_values(omap.prob, *(thresholds or (None, None))))]
    for topic, cells in layers:
        if cells.shape != spec.shape:
            raise ValueError(f"layer {topic} of shape {cells.shape} for a grid of {spec.shape}")
        grids.append((topic, cells))
    with atomic_write(path, "the map") as tmp, open(tmp, "wb") as handle:
        writer = mcap_writer(handle)
        writer.start(profile="ros2", library=LIBRARY)
        schema_id = writer.register_schema(MAP_SCHEMA, "ros2msg", text.encode("utf-8"))
        for topic, cells in grids:
            channel_id = writer.register_channel(
                topic,
                "cdr",
                schema_id,
                metadata={"offered_qos_profiles": qos_profiles_yaml(1, "transient_local")},
            )
            data = _with_cells(empty, cells)
            writer.add_message(channel_id, int(stamp_ns), data, int(stamp_ns))
        writer.finish()  # type: ignore[no-untyped-call]
    return path
