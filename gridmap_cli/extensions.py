"""gridmap's optional C extensions (``setup.py``), loaded once, or None for the reference path.

The extensions are optional at install time: where no C compiler was at hand, importing one
fails and the numpy / Python reference does the work, with the same results. :data:`KERNELS`
set to ``"numpy"`` makes every caller take the reference (tests and benches compare the two);
``"compiled"`` makes a missing extension an error instead of a silent fallback (tests, so that a
broken build is seen).
"""

from __future__ import annotations

import importlib
from types import ModuleType

#: ``"auto"`` (the extension where it imports), ``"numpy"`` (always the reference) or
#: ``"compiled"`` (the extension, or ImportError).
KERNELS = "auto"

_loaded: dict[str, ModuleType | None] = {}


def optional(name: str) -> ModuleType | None:
    """The extension module ``name``, or None when the reference path should do the work."""
    choice = KERNELS
    if choice == "numpy":
        return None
    if _loaded.get(name) is None and (name not in _loaded or choice == "compiled"):
        try:
            _loaded[name] = importlib.import_module(name)
        except ImportError:
            if choice == "compiled":
                raise
            _loaded[name] = None
    return _loaded[name]
