"""The logs in samples/ are what `gridmap simulate` makes from the worlds and paths beside them.

Each sample says in its own ``# key: value`` lines how it was made (robot, seed, drift, world and
path, relative to the repository root); re-running the command with those values must give the
committed bytes. When the simulator changes on purpose, `make samples` regenerates them.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner
from mcap.reader import make_reader

from gridmap_cli.cli import cli
from gridmap_cli.readers.ros.mcap.channels import METADATA_NAME

REPO = Path(__file__).resolve().parent.parent
SAMPLES = REPO / "samples"
NAMES = [
    "corridor_loop.csv",
    "office.csv",
    "hall.csv",
    "corridor_loop.2d",
    "corridor_loop.mcap",
    "corridor_loop_ros2.mcap",
]


def metadata_lines(path: Path) -> dict[str, str]:
    """The ``# key: value`` lines before the header row (an MCAP's ``gridmap`` metadata)."""
    if path.suffix == ".mcap":
        with path.open("rb") as handle:
            records = [m for m in make_reader(handle).iter_metadata() if m.name == METADATA_NAME]
        return dict(records[0].metadata) if records else {}
    meta: dict[str, str] = {}
    with path.open(encoding="utf-8") as handle:
        for line in handle:
            if line.strip() == "LaserOdometryLog":  # an ARIA log's first line
                continue
            if not line.startswith("#"):
                break
            key, sep, value = line[1:].partition(":")
            if sep:
                meta[key.strip()] = value.strip()
    return meta


def first_difference(a: bytes, b: bytes) -> int:
    """1-based line number of the first line where ``a`` and ``b`` differ."""
    for number, (x, y) in enumerate(zip(a.splitlines(), b.splitlines(), strict=False), start=1):
        if x != y:
            return number
    return min(a.count(b"\n"), b.count(b"\n")) + 1


def test_every_sample_log_is_checked() -> None:
    logs = [*SAMPLES.glob("*.csv"), *SAMPLES.glob("*.2d"), *SAMPLES.glob("*.mcap")]
    assert sorted(p.name for p in logs) == sorted(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_sample_is_what_simulate_makes(
    name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    sample = SAMPLES / name
    meta = metadata_lines(sample)
    missing = {"robot", "seed", "drift", "rate", "world", "path"} - meta.keys()
    assert not missing, f"{sample} lacks metadata {sorted(missing)}; run `make samples`"
    # the world and path are named relative to the repository root, as make_samples runs it
    assert not Path(meta["world"]).is_absolute() and not Path(meta["path"]).is_absolute()
    assert (REPO / meta["world"]).is_file() and (REPO / meta["path"]).is_file()

    monkeypatch.chdir(REPO)
    out = tmp_path / name
    result = CliRunner().invoke(
        cli,
        [
            "simulate",
            meta["world"],
            meta["path"],
            "-o",
            str(out),
            "--robot",
            meta["robot"],
            "--seed",
            meta["seed"],
            "--drift",
            meta["drift"],
            "--rate",
            meta["rate"],
            *(["--duration", meta["duration"]] if "duration" in meta else []),
            *(["--encoding", "ros2"] if name.endswith("_ros2.mcap") else []),
            "--quiet",
        ],
    )
    if result.exception and not isinstance(result.exception, SystemExit):
        raise result.exception
    assert result.exit_code == 0, result.stderr

    made, committed = out.read_bytes(), sample.read_bytes()
    if made != committed and sample.suffix == ".mcap":
        pytest.fail(
            f"samples/{name} differs from what `gridmap simulate` makes now ({len(made)} bytes "
            f"made, {len(committed)} committed); if the writer (or the zstandard library, which "
            "compresses the chunks) changed on purpose, run `make samples` and commit the result",
            pytrace=False,
        )
    if made != committed:
        pytest.fail(
            f"samples/{name} differs from what `gridmap simulate` makes now (first at line "
            f"{first_difference(made, committed)}); if the simulator changed on purpose, "
            "run `make samples` and commit the result",
            pytrace=False,
        )
