"""An input that cannot be read is bad data (exit 1, one ``Error:`` line naming it), as a
missing file is, on every command and every input option: a file without read permission, a
directory where a file is expected, a symbolic link to nothing (issue 21; click's own check of
readability gave exit 2)."""

from __future__ import annotations

import builtins
import io
import os
from pathlib import Path

import pytest

from tests.corpus.test_corpus import GOOD_CSV
from tests.helpers import run

SAMPLES = Path(__file__).resolve().parents[2] / "samples"

#: Each command with ``{}`` where the unreadable input goes; ``{good}``, ``{map}``, ``{out}``
#: are a good CSV log, a good map YAML and an output folder.
COMMANDS = [
    "build {} -o {out}/m.png",
    "build {good} --mode error-aware --odometry-error {}.yaml -o {out}/m.png",
    "inspect {}",
    "convert {} {out}/o.mcap",
    "calibrate {}",
    "trajectory {} -o {out}/t.csv --pose odometry",
    "trajectory {good} -o {out}/t.csv --pose odometry --relations {}.txt",
    "evaluate {}.yaml --truth {truth} --frame world",
    "evaluate {map} --truth {}.yaml --frame world",
    "evaluate {map} --truth {truth} --log {}",
    "simulate {}.yaml {path} -o {out}/s.csv",
    "simulate {truth} {}.yaml -o {out}/s.csv",
]
KINDS = ["unreadable", "directory", "dangling-symlink"]


@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    folder = tmp_path_factory.mktemp("good")
    log = folder / "good.csv"
    log.write_text(GOOD_CSV)
    code, _, err = run("build", str(log), "-o", str(folder / "m.png"), "-q")
    assert code == 0, err
    path = folder / "path.yaml"
    path.write_text("gridmap-path: 1\nwaypoints: [[0.5, 0.5], [1.5, 0.5]]\n")
    truth = SAMPLES / "worlds" / "hall.yaml"
    return {"good": str(log), "map": str(folder / "m.yaml"), "truth": str(truth), "path": str(path)}


def _deny(monkeypatch: pytest.MonkeyPatch, target: Path) -> None:
    """Make ``target`` unreadable for this process, also as root (who reads a mode 000 file):
    ``os.access`` says no and ``open`` raises what the kernel would."""
    denied = os.path.abspath(target)
    real_open, real_access = builtins.open, os.access

    def fake_open(file: object, *args: object, **kwargs: object) -> object:
        if isinstance(file, (str, os.PathLike)) and os.path.abspath(os.fspath(file)) == denied:
            raise PermissionError(13, "Permission denied", os.fspath(file))
        return real_open(file, *args, **kwargs)  # type: ignore[call-overload]

    def fake_access(path: object, mode: int, *args: object, **kwargs: object) -> bool:
        if isinstance(path, (str, os.PathLike)) and os.path.abspath(os.fspath(path)) == denied:
            return False
        return real_access(path, mode, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(builtins, "open", fake_open)
    monkeypatch.setattr(io, "open", fake_open)
    monkeypatch.setattr(os, "access", fake_access)


def _make(
    kind: str, folder: Path, suffix: str, monkeypatch: pytest.MonkeyPatch
) -> tuple[Path, str]:
    """The unreadable input of ``kind`` (named ``*suffix``) and a fragment its error holds."""
    if kind == "unreadable":
        target = folder / f"secret{suffix}"
        target.write_text(GOOD_CSV)
        target.chmod(0)
        _deny(monkeypatch, target)
        return target, "cannot read"
    if kind == "directory":
        target = folder / f"logs{suffix}"
        target.mkdir()
        (target / "a.csv").write_text(GOOD_CSV)
        return target, "directory"
    target = folder / f"gone{suffix}"
    target.symlink_to(folder / "nowhere.csv")
    return target, "symbolic link"


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("command", COMMANDS)
def test_an_unreadable_input_is_exit_1_with_one_line(
    command: str, kind: str, tmp_path: Path, good: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    suffix = command.partition("{}")[2].split(" ")[0] or ".csv"
    target, fragment = _make(kind, tmp_path, suffix, monkeypatch)
    args = command.replace("{}" + suffix, "{}").format(str(target), out=out, **good).split()
    code, stdout, err = run(*args)
    assert code == 1, err
    assert stdout == ""
    assert err.count("\n") == 1, err
    assert err.startswith(f"Error: {target}: "), err
    assert fragment in err, err
    assert "internal error" not in err
    assert list(out.iterdir()) == []
