"""Which kernels map a batch: the numpy reference or the compiled ones (numba), and the glue.

The compiled kernels (:mod:`gridmap_cli.models._compiled`) give the numpy path's grid bit for
bit, 2 to 4 times faster, but importing numba and loading the cached machine code costs about
0.45 s CPU of start-up (measured on the 2-core bench machine: numba 0.2 s, the cache 0.25 s; a
first run after install also compiles, a few seconds once), about what they save on an hour of
sonar (576,000 readings). So they are used only when the build maps at least
:data:`MIN_COMPILED_ITEMS` readings (:func:`plan`) or one call hands over that many, when numba
is installed, and never with ``GRIDMAP_KERNELS=numpy`` (the reference, for tests and ``make
bench``). ``GRIDMAP_KERNELS=compiled`` forces them for every batch (tests).
"""

from __future__ import annotations

import os
from types import ModuleType
from typing import Any

#: Below this many readings (or rays) in a build, the numpy path is used: the compiled one
#: saves about 1 us a sonar reading or ray and costs about 0.45 s to load.
MIN_COMPILED_ITEMS = 500_000

_module: ModuleType | None = None
_unavailable = False
_planned = 0


def plan(items: int) -> None:
    """Say how many readings the build will map, so that its batches choose as the whole."""
    global _planned
    _planned = items


def compiled(items: int) -> Any:
    """The compiled-kernel module when it should map ``items`` readings, else None."""
    global _module, _unavailable
    choice = os.environ.get("GRIDMAP_KERNELS", "auto")
    if choice == "numpy" or _unavailable:
        return None
    if choice != "compiled" and max(items, _planned) < MIN_COMPILED_ITEMS and _module is None:
        return None  # once loaded, the kernels serve small batches too
    if _module is None:
        try:
            from gridmap_cli.models import _compiled
        except ImportError:  # numba is not installed: the reference path does the work
            _unavailable = True
            return None
        _module = _compiled
    return _module
