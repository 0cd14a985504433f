"""The same recording given twice to build (or inspect, trajectory) is refused, not merged with
its evidence doubled: by resolved path and by content (``readers/repeats.py``)."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import pytest
from rosbags.rosbag2 import StoragePlugin

from gridmap_cli.errors import UsageError
from gridmap_cli.readers.repeats import refuse_repeats
from tests.helpers import names, run
from tests.readers.bag_helpers import write_bag, write_rosbag2
from tests.readers.mcap_helpers import one_sonar_log


def _same(folder: Path, base: Path) -> list[Path]:
    return [base, base]


def _relative(folder: Path, base: Path) -> list[Path]:
    return [base, base.parent / "." / base.name]


def _symlink(folder: Path, base: Path) -> list[Path]:
    link = folder / f"link{base.suffix}"
    link.symlink_to(base)
    return [base, link]


def _copy(folder: Path, base: Path) -> list[Path]:
    copy = folder / f"copy{base.suffix}"
    (shutil.copytree if base.is_dir() else shutil.copyfile)(base, copy)
    return [base, copy]


WAYS: dict[str, Callable[[Path, Path], list[Path]]] = {
    "same name": _same, "another name": _relative, "symlink": _symlink, "copy": _copy,
}  # fmt: skip


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("recordings")
    mcap = one_sonar_log(folder / "run.mcap")
    return {
        "mcap": mcap,
        "bag": write_bag(mcap, folder / "run.bag"),
        "rosbag2": write_rosbag2(mcap, folder / "sqlite"),
    }


@pytest.mark.parametrize("way", sorted(WAYS))
@pytest.mark.parametrize("kind", ["mcap", "bag", "rosbag2"])
def test_a_recording_given_twice_is_refused_before_anything_is_written(
    kind: str, way: str, recordings: dict[str, Path], tmp_path: Path
) -> None:
    given = WAYS[way](tmp_path, recordings[kind])
    out = tmp_path / "out"
    out.mkdir()
    code, _, err = run("build", *map(str, given), "-o", str(out / "m.png"))
    assert code == 2, err
    assert err.count("\n") == 1 and "given twice" in err, err
    how = "the same content" if way == "copy" else "the same file"
    assert f": {how} as " in err
    assert names(out) == set()
    code, _, err = run("inspect", *map(str, given))
    assert code == 2 and "given twice" in err, err


def test_a_rosbag2_folder_and_its_own_files_are_one_recording(tmp_path: Path) -> None:
    mcap = one_sonar_log(tmp_path / "run.mcap")
    sqlite = write_rosbag2(mcap, tmp_path / "sqlite")
    stored = write_rosbag2(mcap, tmp_path / "stored", storage=StoragePlugin.MCAP)
    inner = next(stored.glob("*.mcap"))
    for given in ([sqlite, sqlite / "metadata.yaml"], [stored, inner]):
        code, _, err = run("build", *map(str, given), "-o", str(tmp_path / "m.png"))
        assert code == 2 and "the same file as" in err, err


def test_different_recordings_of_one_size_are_not_the_same(tmp_path: Path) -> None:
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    a.write_bytes(b"\x89MCAP0\r\n" + b"a" * 100)
    b.write_bytes(b"\x89MCAP0\r\n" + b"b" * 100)
    refuse_repeats([a, b])  # no error: their content differs
    b.write_bytes(a.read_bytes())
    with pytest.raises(UsageError, match="the same content as"):
        refuse_repeats([a, b])
