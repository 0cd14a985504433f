"""The readers' compiled inner loops (``gridmap_cli/readers/ros/_cwalk.c``), when they are built.

The MCAP and ROS 1 bag integrity checks walk every record of every chunk. The C walks only say
whether a chunk is sound and where its first unsound record is; the Python walks, which stay the
reference, then word the error, so messages are the same with or without the extension.
:mod:`gridmap_cli.extensions` says how the choice is made and overridden.
"""

from __future__ import annotations

from typing import Any

from gridmap_cli.extensions import optional


def compiled_walk() -> Any:
    """The compiled-walk module, or None when the Python walk should do the work."""
    return optional("gridmap_cli.readers.ros._cwalk")
