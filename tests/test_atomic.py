"""Atomic outputs: a target is replaced whole or not at all, and nothing is left lying around."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from gridmap_cli.atomic import atomic_output, atomic_outputs


class Boom(Exception):
    pass


def names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_success_replaces_the_target(tmp_path: Path) -> None:
    target = tmp_path / "map.pgm"
    with atomic_output(target) as tmp:
        # hidden, beside the target, same suffix (Pillow picks the format from it)
        assert tmp.parent == tmp_path
        assert tmp.name.startswith(".map.pgm.tmp-")
        assert tmp.suffix == ".pgm"
        assert tmp.exists() and not target.exists()
        tmp.write_bytes(b"new")
    assert target.read_bytes() == b"new"
    assert names(tmp_path) == ["map.pgm"]


def test_success_overwrites_an_existing_target(tmp_path: Path) -> None:
    target = tmp_path / "log.csv"
    target.write_text("old")
    with atomic_output(target) as tmp:
        tmp.write_text("new")
        assert target.read_text() == "old"  # untouched until the block ends
    assert target.read_text() == "new"
    assert names(tmp_path) == ["log.csv"]


def test_permissions_are_those_of_a_plain_new_file(tmp_path: Path) -> None:
    plain = tmp_path / "plain.txt"
    plain.write_text("x")
    target = tmp_path / "atomic.txt"
    with atomic_output(target) as tmp:
        tmp.write_text("x")
    assert target.stat().st_mode == plain.stat().st_mode


def test_exception_leaves_neither_target_nor_temporary_file(tmp_path: Path) -> None:
    target = tmp_path / "map.png"
    with pytest.raises(Boom), atomic_output(target) as tmp:
        tmp.write_bytes(b"half")
        raise Boom
    assert names(tmp_path) == []


def test_exception_keeps_an_existing_target(tmp_path: Path) -> None:
    target = tmp_path / "map.png"
    target.write_bytes(b"old")
    with pytest.raises(Boom), atomic_output(target) as tmp:
        tmp.write_bytes(b"half")
        raise Boom
    assert target.read_bytes() == b"old"
    assert names(tmp_path) == ["map.png"]


def test_keyboard_interrupt_also_cleans_up(tmp_path: Path) -> None:
    target = tmp_path / "map.png"
    with pytest.raises(KeyboardInterrupt), atomic_output(target) as tmp:
        tmp.write_bytes(b"half")
        raise KeyboardInterrupt
    assert names(tmp_path) == []


def test_outputs_all_renamed_on_success(tmp_path: Path) -> None:
    image, meta = tmp_path / "m.pgm", tmp_path / "m.yaml"
    with atomic_outputs([image, meta]) as (tmp_image, tmp_meta):
        assert tmp_image.suffix == ".pgm" and tmp_meta.suffix == ".yaml"
        tmp_image.write_bytes(b"P5")
        tmp_meta.write_text("image: m.pgm\n")
        assert not image.exists()  # nothing renamed before the whole block is done
    assert image.read_bytes() == b"P5"
    assert meta.read_text() == "image: m.pgm\n"
    assert names(tmp_path) == ["m.pgm", "m.yaml"]


def test_failure_in_the_second_file_leaves_no_first_file(tmp_path: Path) -> None:
    image, meta = tmp_path / "m.pgm", tmp_path / "m.yaml"
    with pytest.raises(Boom), atomic_outputs([image, meta]) as (tmp_image, tmp_meta):
        tmp_image.write_bytes(b"P5 complete image")
        tmp_meta.write_text("image: m.p")
        raise Boom
    assert names(tmp_path) == []


def test_failed_rename_of_a_later_target_removes_the_earlier_new_one(tmp_path: Path) -> None:
    image, meta = tmp_path / "m.pgm", tmp_path / "m.yaml"
    meta.mkdir()  # os.replace cannot put a file over a directory
    with pytest.raises(OSError), atomic_outputs([image, meta]) as (tmp_image, tmp_meta):
        tmp_image.write_bytes(b"new image")
        tmp_meta.write_text("new yaml")
    assert names(tmp_path) == ["m.yaml"]
    assert meta.is_dir()


def test_failed_rename_restores_the_earlier_target_it_replaced(tmp_path: Path) -> None:
    image, meta = tmp_path / "m.pgm", tmp_path / "m.yaml"
    image.write_bytes(b"old image")
    meta.mkdir()
    with pytest.raises(OSError), atomic_outputs([image, meta]) as (tmp_image, tmp_meta):
        tmp_image.write_bytes(b"new image")
        tmp_meta.write_text("new yaml")
    assert image.read_bytes() == b"old image"
    assert names(tmp_path) == ["m.pgm", "m.yaml"]


def test_outputs_in_different_folders(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    first, second = tmp_path / "a" / "x.txt", tmp_path / "b" / "y.txt"
    with atomic_outputs([first, second]) as temps:
        assert [t.parent for t in temps] == [first.parent, second.parent]
        for t in temps:
            t.write_text(t.parent.name)
    assert first.read_text() == "a" and second.read_text() == "b"


def test_the_same_output_twice_is_refused(tmp_path: Path) -> None:
    target = tmp_path / "m.pgm"
    with pytest.raises(ValueError, match="twice"), atomic_outputs([target, target]):
        pass
    assert names(tmp_path) == []


def test_missing_folder_raises_and_creates_nothing(tmp_path: Path) -> None:
    target = tmp_path / "no" / "such" / "m.pgm"
    with pytest.raises(FileNotFoundError), atomic_output(target):
        pass
    assert names(tmp_path) == []
    assert not os.path.exists(tmp_path / "no")


# ---------------------------------------------------------------- leftovers of a killed writer

_KILLED_WRITER = """
import os, sys, time
from pathlib import Path
from gridmap_cli.atomic import atomic_outputs, _commit
stage = sys.argv[2]
targets = [Path(sys.argv[1]) / "map.png", Path(sys.argv[1]) / "map.yaml"]
if stage == "commit":
    import gridmap_cli.atomic as atomic
    real = os.replace
    def slow_replace(src, dst):
        real(src, dst)
        print("renamed", flush=True)
        time.sleep(60)  # killed here: between the renames of the image and its YAML
    atomic.os.replace = slow_replace
with atomic_outputs(targets) as temps:
    for tmp in temps:
        tmp.write_bytes(b"new")
    if stage == "write":
        print("writing", flush=True)
        time.sleep(60)  # killed here: temporary files written, nothing renamed
"""


def _kill_while(tmp_path: Path, stage: str) -> None:
    """Run a writer of map.png + map.yaml in ``tmp_path`` and SIGKILL it at ``stage``."""
    import signal
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-c", _KILLED_WRITER, str(tmp_path), stage],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() in ("writing", "renamed")
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()


def test_the_next_run_cleans_what_a_killed_writer_left(tmp_path: Path) -> None:
    (tmp_path / "map.png").write_bytes(b"old")
    (tmp_path / "map.yaml").write_bytes(b"old")
    _kill_while(tmp_path, "write")
    left = [n for n in names(tmp_path) if n.startswith(".")]
    assert len(left) == 2 and all(".tmp-" in n for n in left)
    # the outputs were never missing nor half-written
    assert (tmp_path / "map.png").read_bytes() == b"old"
    unrelated = [tmp_path / ".other.png.tmp-1-0123abcd.png", tmp_path / ".map.png.tmp-notmine"]
    for path in unrelated:
        path.write_bytes(b"not ours")
    with atomic_outputs([tmp_path / "map.png", tmp_path / "map.yaml"]) as temps:
        for tmp in temps:
            tmp.write_bytes(b"next")
    assert names(tmp_path) == sorted(
        ["map.png", "map.yaml", ".other.png.tmp-1-0123abcd.png", ".map.png.tmp-notmine"]
    )
    assert (tmp_path / "map.png").read_bytes() == b"next"


def test_a_writer_killed_between_renames_leaves_every_output_present(tmp_path: Path) -> None:
    (tmp_path / "map.png").write_bytes(b"old")
    (tmp_path / "map.yaml").write_bytes(b"old")
    _kill_while(tmp_path, "commit")
    # image renamed, YAML not yet: both present, each old or new whole; a backup is left over
    assert (tmp_path / "map.png").read_bytes() == b"new"
    assert (tmp_path / "map.yaml").read_bytes() == b"old"
    assert any(".bak-" in n for n in names(tmp_path))
    with atomic_outputs([tmp_path / "map.png", tmp_path / "map.yaml"]) as temps:
        for tmp in temps:
            tmp.write_bytes(b"next")
    assert names(tmp_path) == ["map.png", "map.yaml"]


def test_a_live_writers_files_are_left_alone(tmp_path: Path) -> None:
    from gridmap_cli.atomic import clean_leftovers

    live = tmp_path / f".map.png.tmp-{os.getppid()}-0123abcd.png"
    dead_old_style = tmp_path / ".map.png.bak-0123abcd.png"
    live.write_bytes(b"x")
    dead_old_style.write_bytes(b"x")
    assert clean_leftovers(tmp_path / "map.png") == [dead_old_style]
    assert live.exists()
