"""What every writer shares (gridmap_cli/writers/__init__.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gridmap_cli.errors import OutputExistsError, UsageError
from gridmap_cli.writers import check_output


def test_check_output_refuses_a_directory_even_with_force(tmp_path: Path) -> None:
    for force in (False, True):
        with pytest.raises(UsageError, match=rf"^{tmp_path} is a directory$"):
            check_output(tmp_path, force)


def test_check_output_refuses_an_existing_file_without_force(tmp_path: Path) -> None:
    target = tmp_path / "out.csv"
    check_output(target, force=False)  # nothing there yet
    target.write_text("old")
    with pytest.raises(OutputExistsError, match=r"out\.csv exists \(use --force to overwrite\)"):
        check_output(target, force=False)
    check_output(target, force=True)
    assert target.read_text() == "old"
