"""Stamps that never advance or jump by years: warned once, and no window on them (issue 21)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers import names, run
from tests.readers.carmen_helpers import flaser, odom, write

RANGES = [1.0, 2.0, 1.5, 2.0, 1.0] * 36  # 180 beams


def drive(stamps: list[float]) -> list[str]:
    lines = []
    for i, t in enumerate(stamps):
        pose = (0.1 * i, 0.0, 0.0)
        lines += [odom(pose, t), flaser(RANGES, pose, t)]
    return lines


FROZEN = [1_000.0] * 20
JUMPED = [1.6e9 + i for i in range(10)] + [4.3e9 + i for i in range(10)]  # 2020, then 2106
STEADY = [1.6e9 + i for i in range(20)]


@pytest.mark.parametrize(
    ("stamps", "said"),
    [(FROZEN, "the stamps do not advance"), (JUMPED, "the stamps jump by 86 years")],
)
def test_build_warns_once_and_maps(tmp_path: Path, stamps: list[float], said: str) -> None:
    log = write(tmp_path, drive(stamps))
    code, _, err = run("build", str(log), "-o", str(tmp_path / "map.png"))
    assert code == 0, err
    assert err.count(said) == 1
    assert (tmp_path / "map.png").exists()


@pytest.mark.parametrize("stamps", [FROZEN, JUMPED])
def test_inspect_shows_the_warning(tmp_path: Path, stamps: list[float]) -> None:
    code, out, err = run("inspect", str(write(tmp_path, drive(stamps))))
    assert code == 0, err
    assert "Warning: " in out and "time windows mean nothing" in out


@pytest.mark.parametrize("stamps", [FROZEN, JUMPED])
@pytest.mark.parametrize("window", [("--end", "60"), ("--start", "1"), ("--start", "2020-09-13")])
def test_a_window_such_stamps_cannot_honour_is_refused(
    tmp_path: Path, stamps: list[float], window: tuple[str, str]
) -> None:
    log = write(tmp_path, drive(stamps))
    out = tmp_path / "out"
    out.mkdir()
    code, _, err = run("build", str(log), "-o", str(out / "map.png"), "--pose", "odometry", *window)
    assert code == 1
    assert err.startswith(f"Error: {log}: {' '.join(window)} cannot be honoured: ")
    assert len(err.strip().splitlines()) == 1
    assert names(out) == set()


def test_steady_stamps_say_nothing(tmp_path: Path) -> None:
    log = write(tmp_path, drive(STEADY))
    code, _, err = run(
        "build", str(log), "-o", str(tmp_path / "map.png"), "--pose", "odometry", "--end", "10"
    )
    assert code == 0, err
    assert "Warning" not in err
