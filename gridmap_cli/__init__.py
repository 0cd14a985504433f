"""gridmap: occupancy-grid maps from robot logs of range readings and wheel odometry.

The Python API (docs/python-api.md): :func:`read_log` reads a log, :class:`MapOptions` says
how to map it and makes a :class:`BuildRequest`, :func:`build` returns a :class:`MapBuild` (the
map, the track it was built with, warnings), :func:`write_map` writes the map_server files.
Every refusal is a :class:`GridmapError`. The names are imported when first used, so that
``import gridmap_cli`` stays cheap.

The packages are the stages of the flow (README, "Architecture"): readers -> poses -> mapping ->
writers, with robot, sim, evaluation, runs, describe and cli beside them. The modules at this
level are the core every stage may import (errors, records, atomic, limits, geometry,
yamlfile, heap, extensions); they import no package but :mod:`gridmap_cli.robot`.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

if TYPE_CHECKING:
    from gridmap_cli.errors import GridmapError
    from gridmap_cli.poses.sources import SOURCES
    from gridmap_cli.readers import read_log
    from gridmap_cli.robot import load_robot
    from gridmap_cli.runs.build import BuildRequest, MapBuild, build
    from gridmap_cli.runs.settings import MapOptions
    from gridmap_cli.writers.map_image import write_map

#: Each exported name and the module it lives in.
_EXPORTS = {
    "GridmapError": "gridmap_cli.errors",
    "SOURCES": "gridmap_cli.poses.sources",
    "read_log": "gridmap_cli.readers",
    "load_robot": "gridmap_cli.robot",
    "BuildRequest": "gridmap_cli.runs.build",
    "MapBuild": "gridmap_cli.runs.build",
    "build": "gridmap_cli.runs.build",
    "MapOptions": "gridmap_cli.runs.settings",
    "write_map": "gridmap_cli.writers.map_image",
}

__all__ = [
    "SOURCES",
    "BuildRequest",
    "GridmapError",
    "MapBuild",
    "MapOptions",
    "__version__",
    "build",
    "load_robot",
    "read_log",
    "write_map",
]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'gridmap_cli' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)
