"""Which kernels map a batch: the numpy reference or the compiled ones.

The compiled kernels are a small C extension (``gridmap_cli/mapping/models/_ckernels.c``, built by
``pip install``). Each repeats its numpy reference operation for operation, so the grids are
equal bit for bit (tests/models/test_kernels.py), and loading them costs well under a
millisecond, so they map every batch when they are built. :mod:`gridmap_cli.extensions` says
how the choice is made and overridden (:data:`~gridmap_cli.extensions.KERNELS`).
"""

from __future__ import annotations

from typing import Any

from gridmap_cli.extensions import optional


def compiled() -> Any:
    """The compiled-kernel module, or None when the numpy reference should do the work."""
    return optional("gridmap_cli.mapping.models._ckernels")
