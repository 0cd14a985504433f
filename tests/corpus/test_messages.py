"""Messages are for people: numbers in errors and warnings read as numbers, never as numpy's
reprs (``np.float64(nan)``, which a tuple of numpy scalars or ``!r`` gives); every corpus case is
also scanned for them (``test_corpus.py``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.cli.common import plain_numbers
from gridmap_cli.errors import InputFileError
from tests.corpus.test_corpus import GOOD_CSV
from tests.helpers import run


def test_numpy_scalar_reprs_read_as_their_values() -> None:
    values = (np.float64("nan"), np.int32(3), np.float32(1.5), np.True_, np.str_("a"))
    assert plain_numbers(repr(values)) == "(nan, 3, 1.5, True, 'a')"
    assert plain_numbers(f"got {np.float64(-2.25)!r} at {np.int64(7)!r}") == "got -2.25 at 7"
    assert plain_numbers("numpy np.float64 stays, so does inp.x(1)") == (
        "numpy np.float64 stays, so does inp.x(1)"
    )


def test_an_error_carrying_numpy_scalars_prints_plain_numbers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import gridmap_cli.readers.text.csv_log as csv_log

    def broken(*args: object, **kwargs: object) -> None:
        pose = (np.float64(1.0), np.float64("nan"))
        raise InputFileError(tmp_path / "log.csv", f"pose {pose} is not finite", 7)

    monkeypatch.setattr(csv_log, "read_csv_log", broken)
    log = tmp_path / "log.csv"
    log.write_text(GOOD_CSV)
    code, _, err = run("build", str(log), "-o", str(tmp_path / "m.png"))
    assert code == 1
    assert err == f"Error: {log}:7: pose (1.0, nan) is not finite\n"


def test_odometry_error_coefficients_say_nan_plainly() -> None:
    from gridmap_cli.poses.odometry_error import OdometryError

    with pytest.raises(ValueError, match=r"got nan$"):
        OdometryError(sonar_relative_error=np.float64("nan"))
