"""The pose-spread layer written beside a map: how far each cell can be trusted.

Per cell, the position spread (metres, one standard deviation) of the poses whose readings made
it (:func:`~gridmap_cli.evaluation.spread_map.spread_layer`), stored as a second map_server map
(``MAP_spread.png`` + ``MAP_spread.yaml``, ``mode: raw``) and, in an MCAP map, as a second
OccupancyGrid on ``/map_spread``. Both hold the same cell values: level = round(spread /
:data:`SPREAD_M_PER_LEVEL`), capped at :data:`SPREAD_TOP_LEVEL` (2 m or more), unknown where the
map is unknown (grey 255 in the image, -1 in the grid). A raw map loads as those levels
(occupancy 0..100), so RViz or Foxglove shows a well placed cell as 0 and a lost one as 100, and
the spread in metres is the value times 0.02. The YAML says so in a comment, which every loader
skips.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt
from PIL import Image

from gridmap_cli.mapping.grid import GridSpec
from gridmap_cli.writers.map_image import ExtraOutput, map_yaml_text

#: Metres of position spread per level (grey value of the image, cell value of the grid).
SPREAD_M_PER_LEVEL = 0.02
#: The top level: a spread of 2 m or more, past which a map's walls are no longer where it draws
#: them.
SPREAD_TOP_LEVEL = 100
#: Grey of a cell the map does not know (raw mode: above 100, which every loader reads unknown).
SPREAD_UNKNOWN_GREY = 255
#: The MCAP topic of the layer, beside the map's ``/map``.
SPREAD_TOPIC = "/map_spread"


def spread_paths(image_path: Path) -> tuple[Path, Path]:
    """The layer's image and YAML beside the map image ``image_path``: ``STEM_spread.png`` and
    ``STEM_spread.yaml``."""
    stem = Path(image_path).stem
    return (
        image_path.with_name(f"{stem}_spread.png"),
        image_path.with_name(f"{stem}_spread.yaml"),
    )


def spread_levels(spread_m: npt.NDArray[np.float64]) -> npt.NDArray[np.int8]:
    """The cell values of a layer (metres, NaN unknown; shape (height, width), row 0 at the
    bottom): round(spread / 0.02) capped at 100, -1 unknown; the OccupancyGrid's values."""
    unknown = np.isnan(spread_m)
    level = np.rint(np.where(unknown, 0.0, spread_m) / SPREAD_M_PER_LEVEL)
    out = np.minimum(level, SPREAD_TOP_LEVEL).astype(np.int8)
    out[unknown] = -1
    return out


def spread_pixels(spread_m: npt.NDArray[np.float64]) -> npt.NDArray[np.uint8]:
    """The layer as a raw map image, top row first: grey = level, 255 unknown."""
    levels = spread_levels(spread_m)
    grey = levels.astype(np.uint8)
    grey[levels < 0] = SPREAD_UNKNOWN_GREY
    out: npt.NDArray[np.uint8] = np.ascontiguousarray(grey[::-1])
    return out


def spread_yaml_text(image_name: str, spec: GridSpec) -> str:
    """The layer's map_server YAML (raw mode, the map's geometry) with its scale in a comment."""
    scale = (
        f"# pose spread: each grey level (a raw map's occupancy value) is {SPREAD_M_PER_LEVEL:g} m "
        f"of position spread (one standard deviation); {SPREAD_TOP_LEVEL} is "
        f"{SPREAD_M_PER_LEVEL * SPREAD_TOP_LEVEL:g} m or more; {SPREAD_UNKNOWN_GREY} unknown\n"
    )
    return scale + map_yaml_text(image_name, "raw", spec, 0.65, 0.25)


def spread_output(
    image_path: Path, spread_m: npt.NDArray[np.float64], spec: GridSpec
) -> ExtraOutput:
    """The layer's two files beside the map image ``image_path``, for
    :func:`~gridmap_cli.writers.map_image.write_map`'s ``also`` (written with the map, or not at
    all)."""
    image, yaml_path = spread_paths(image_path)
    text = spread_yaml_text(image.name, spec)

    def write(temps: list[Path]) -> None:
        Image.fromarray(spread_pixels(spread_m)).save(temps[0], format="PNG")
        temps[1].write_text(text, encoding="utf-8")

    return (image, yaml_path), write
