"""Optional C extensions: loaded once, None when missing, an error only when asked for."""

from __future__ import annotations

import pytest

from gridmap_cli import extensions


def test_a_missing_extension_falls_back_unless_compiled_is_asked(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(extensions, "_loaded", {})
    name = "gridmap_cli._no_such_extension"
    monkeypatch.setattr(extensions, "KERNELS", "auto")
    assert extensions.optional(name) is None
    monkeypatch.setattr(extensions, "KERNELS", "compiled")
    with pytest.raises(ImportError):
        extensions.optional(name)


def test_a_present_extension_is_loaded_once_and_numpy_turns_it_off(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(extensions, "_loaded", {})
    monkeypatch.setattr(extensions, "KERNELS", "auto")
    first = extensions.optional("gridmap_cli.readers.ros._cwalk")
    assert first is not None and extensions.optional("gridmap_cli.readers.ros._cwalk") is first
    monkeypatch.setattr(extensions, "KERNELS", "numpy")
    assert extensions.optional("gridmap_cli.readers.ros._cwalk") is None
