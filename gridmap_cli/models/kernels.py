"""Which kernels map a batch: the numpy reference or the compiled ones, and the glue.

The compiled kernels are a small C extension (``gridmap_cli/models/_ckernels.c``, built by
``pip install``). Each repeats its numpy reference operation for operation, so the grids are
equal bit for bit (tests/models/test_kernels.py), 3 to 10 times faster, and loading them costs
well under a millisecond, so they map every batch when they are built. The extension is
optional: without a C compiler at install time, the numpy path does the work.
``GRIDMAP_KERNELS=numpy`` forces the reference (tests, ``make bench``); ``GRIDMAP_KERNELS=
compiled`` makes a missing extension an error instead of a silent fallback (tests).
"""

from __future__ import annotations

import os
from types import ModuleType
from typing import Any

_module: ModuleType | None = None
_unavailable = False


def compiled() -> Any:
    """The compiled-kernel module, or None when the numpy reference should do the work."""
    global _module, _unavailable
    choice = os.environ.get("GRIDMAP_KERNELS", "auto")
    if choice == "numpy":
        return None
    if _module is None and (not _unavailable or choice == "compiled"):
        try:
            from gridmap_cli.models import _ckernels  # type: ignore[attr-defined]
        except ImportError:
            if choice == "compiled":
                raise
            _unavailable = True
            return None
        _module = _ckernels
    return _module
