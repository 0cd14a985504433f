"""The compiled record walks (``gridmap_cli/readers/_cwalk.c``), when they are built.

The MCAP and ROS 1 bag integrity checks walk every record of every chunk. The C walks only say
whether a chunk is sound and where its first unsound record is; the Python walks, which stay the
reference, then word the error, so messages are the same with or without the extension. Like
the mapping kernels (:mod:`gridmap_cli.models.kernels`), the extension is optional at install
time, and ``GRIDMAP_KERNELS=numpy`` makes the Python reference do every walk.

The extension also matches gridmap's compact JSON messages (``_cjson.c``, for
:mod:`~gridmap_cli.readers.json_bulk`), where the numpy matcher stays the reference.
"""

from __future__ import annotations

import os
from types import ModuleType
from typing import Any

_module: ModuleType | None = None
_unavailable = False


def compiled_walk() -> Any:
    """The compiled-walk module, or None when the Python walk should do the work."""
    global _module, _unavailable
    choice = os.environ.get("GRIDMAP_KERNELS", "auto")
    if choice == "numpy":
        return None
    if _module is None and (not _unavailable or choice == "compiled"):
        try:
            from gridmap_cli.readers import _cwalk  # type: ignore[attr-defined]
        except ImportError:
            if choice == "compiled":
                raise
            _unavailable = True
            return None
        _module = _cwalk
    return _module
