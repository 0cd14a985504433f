"""Run gridmap on every case of the malformed-input corpus (``tests/corpus/generate.py``).

Each case must give its exit code, exactly one ``Error:`` line that names the broken file and
the place (line, byte offset or message index) and says what is wrong, and leave the output
folder as it was: a good map already there is neither changed nor joined by anything.
"""

from __future__ import annotations

import hashlib
from collections import Counter
from pathlib import Path

import pytest

from tests.corpus.generate import all_cases, build_case, good_inputs, named_path
from tests.helpers import run

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
CASES = {c.name: c for c in all_cases()}
GOOD_CSV = "# robot: p3dx\ntime,x,y,theta,sonar0,sonar1\n" + "".join(
    f"{k / 10:.1f},{k * 0.05:.2f},0.0,0.0,1.5,2.0\n" for k in range(6)
)


def snapshot(folder: Path) -> dict[str, str]:
    return {
        p.name: hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.iterdir())
        if p.is_file()
    }


@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A good CSV log, a good waypoint path, and a good map to leave untouched."""
    folder = tmp_path_factory.mktemp("good")
    log = folder / "good.csv"
    log.write_text(GOOD_CSV)
    path = folder / "path.yaml"
    path.write_text("gridmap-path: 1\nwaypoints: [[0.5, 0.5], [1.5, 0.5]]\n")
    code, _, err = run("build", str(log), "-o", str(folder / "m.png"), "-q")
    assert code == 0, err
    return {"csv": log, "path": path, "map": folder / "m.png", "yaml": folder / "m.yaml"}


def test_the_corpus_covers_every_reader_with_80_cases_or_more() -> None:
    readers = Counter(c.reader for c in CASES.values())
    assert set(readers) == {
        "csv", "aria", "mcap", "bag", "rosbag2", "carmen", "robot", "aria-params", "world"
    }  # fmt: skip
    assert sum(readers.values()) >= 80


def test_the_unbroken_inputs_succeed(tmp_path: Path, good: dict[str, Path]) -> None:
    for command, path in good_inputs(tmp_path):
        out = tmp_path / f"{path.name}.png"
        if command == "build":
            args = ["build", str(path), "-o", str(out)]
        elif command == "robot":
            args = ["build", str(good["csv"]), "--robot", str(path), "-o", str(out)]
        else:
            args = ["simulate", str(path), str(good["path"]), "-o", str(tmp_path / "s.csv")]
        code, _, err = run(*args, "-q")
        assert code == 0, f"{path}: {err}"


@pytest.mark.parametrize("name", sorted(CASES))
def test_case(name: str, tmp_path: Path, good: dict[str, Path]) -> None:
    c = CASES[name]
    given = build_case(name, tmp_path / "case")
    out = tmp_path / "out"
    out.mkdir()
    for key in ("map", "yaml"):
        (out / good[key].name).write_bytes(good[key].read_bytes())
    (out / "s.csv").write_text("a log simulate must not replace\n")
    before = snapshot(out)
    target = str(out / "m.png")
    if c.command == "build":
        # the odometry, as the cases were written for: a laser case would otherwise be mapped
        # by the pose graph the automatic choice picks, past the odometry the case breaks
        args = ["build", str(given), "-o", target, "--force", "--pose", "odometry"]
    elif c.command == "robot":
        args = ["build", str(good["csv"]), "--robot", str(given), "-o", target, "--force"]
    else:
        args = ["simulate", str(given), str(good["path"]), "-o", str(out / "s.csv"), "--force"]
    code, stdout, err = run(*args)
    assert code == c.code, err
    assert stdout == ""
    assert err.count("\n") == 1, err
    expected = f"Error: {named_path(c, tmp_path / 'case')}{c.place}"
    assert err.startswith(expected), f"{err!r} does not start with {expected!r}"
    assert c.fragment in err, err
    assert "internal error" not in err and "Traceback" not in err
    assert "np." not in err, err  # numpy reprs (np.float64(nan)) are not for people
    assert snapshot(out) == before
    if c.command == "build":  # inspect reads it as build does: no crash, no numpy reprs
        code, stdout, err = run("inspect", str(given))
        assert "internal error" not in err and "Traceback" not in err, err
        assert "np." not in stdout + err, stdout + err
