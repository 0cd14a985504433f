"""The same simulated run stored in any format is the same data and the same map.

Formats are containers, not models: whatever a log is stored in, gridmap must read back the same
canonical records (after sync: the same readings with the same sensor poses) and write the same
map bytes, in every map mode. The goldens for samples/ live in samples/golden/ and change only
through `make goldens` (tests/golden.py says what they hold).
"""

from __future__ import annotations

import shlex
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.mapping.mapfile import load_map
from gridmap_cli.mapping.pipeline import BuildOptions, build_map
from gridmap_cli.poses.sync import synchronise
from gridmap_cli.readers import read_log
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RobotDescription, load_robot
from gridmap_cli.sim.path import parse_path_yaml
from gridmap_cli.sim.simulate import simulate
from gridmap_cli.sim.world import World
from gridmap_cli.writers.aria_log import save_aria_log
from gridmap_cli.writers.csv_log import save_csv_log
from gridmap_cli.writers.map_image import write_map
from tests.golden import (
    DUMP_HEAD,
    DUMP_NAME,
    GOLDEN,
    HEAD_LINES,
    REGENERATE,
    RUN,
    SAMPLE_LOGS,
    canonical_dump,
    log_robot,
    map_outputs,
    read_sums,
    sha256,
)
from tests.helpers import run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
#: The format each sample is stored in, as `gridmap convert` names it (format, encoding).
STORED_AS = {
    "corridor_loop.csv": ("csv", None),
    "corridor_loop.2d": ("aria", None),
    "corridor_loop.mcap": ("mcap", "json"),
    "corridor_loop_ros2.mcap": ("mcap", "ros2"),
}
SUFFIX = {"csv": ".csv", "aria": ".2d", "mcap": ".mcap"}
PATH = "gridmap-path: 1\nwaypoints: [[2.0, 2.0], [12.0, 2.0], [20.0, 2.0], [20.0, 6.0]]\n"


@pytest.fixture(scope="module")
def stored(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    loaded = load_map(SAMPLES / "worlds" / "corridor_loop.yaml")
    robot = load_robot("p3at")
    log = simulate(
        World(loaded.occupied_mask(), loaded.spec),
        parse_path_yaml(PATH, "inline.yaml"),
        robot,
        seed=4,
        drift=1.0,
    )
    folder = tmp_path_factory.mktemp("conformance")
    log.metadata["robot"] = "p3at"
    save_csv_log(log, folder / "run.csv")
    save_aria_log(log, robot.sensors, folder / "run.2d")
    return folder / "run.csv", folder / "run.2d"


def test_both_formats_read_back_the_same_records(stored: tuple[Path, Path]) -> None:
    csv_path, aria_path = stored
    a, b = read_log(csv_path), read_log(aria_path)
    robot = load_robot("p3at")
    for track_a, track_b in ((a.poses, b.poses), (a.truth, b.truth)):
        assert track_a is not None and track_b is not None
        for field in ("stamp_ns", "x_m", "y_m", "theta_rad"):
            assert np.array_equal(getattr(track_a, field), getattr(track_b, field)), field
    ra, sa = synchronise(a, robot)
    rb, sb = synchronise(b, robot)
    assert sa == sb
    assert ra.sensors == rb.sensors  # the .2d header's sonarUnit lines give the preset geometry
    for field in ("stamp_ns", "sensor", "range_m", "x_m", "y_m", "theta_rad"):
        assert np.array_equal(getattr(ra, field), getattr(rb, field)), field


@pytest.mark.parametrize(
    ("mode", "suffix"), [("trinary", ".pgm"), ("scale", ".png"), ("raw", ".png")]
)
def test_both_formats_build_byte_identical_maps(
    stored: tuple[Path, Path], tmp_path: Path, mode: str, suffix: str
) -> None:
    images = []
    for i, log_path in enumerate(stored):
        result = build_map(read_log(log_path), load_robot("p3at"), BuildOptions())
        image, yaml_path = write_map(tmp_path / f"map{i}{suffix}", result.map, mode=mode)
        images.append((image.read_bytes(), yaml_path.read_text().replace(f"map{i}", "map")))
    assert images[0] == images[1]
    assert len(images[0][0]) > 1000  # a real map, not an empty file


def first_difference(name: str, text: str, reference: str) -> str:
    """Where ``text`` first departs from ``reference``, for an assertion message (the dumps run
    to 1.7 MB: pytest's own diff of them would drown the point)."""
    lines, ref = text.splitlines(), reference.splitlines()
    for number, (a, b) in enumerate(zip(lines, ref, strict=False), start=1):
        if a != b:
            return f"{name}: dump line {number} is {a!r}, the CSV's is {b!r}"
    return f"{name}: dump has {len(lines)} lines, the CSV's {len(ref)}"


@pytest.fixture(scope="module")
def samples_read() -> dict[str, tuple[RangeLog, RobotDescription | None]]:
    """Each sample read through the registry, with the robot its robot line names (p3at)."""
    out = {}
    for name in SAMPLE_LOGS:
        log = read_log(SAMPLES / name)
        out[name] = (log, log_robot(log))
    return out


@pytest.fixture(scope="module")
def dumps(samples_read: dict[str, tuple[RangeLog, RobotDescription | None]]) -> dict[str, str]:
    return {name: canonical_dump(log, robot) for name, (log, robot) in samples_read.items()}


@pytest.fixture(scope="module")
def maps(
    samples_read: dict[str, tuple[RangeLog, RobotDescription | None]],
    tmp_path_factory: pytest.TempPathFactory,
) -> dict[str, dict[str, bytes]]:
    out = {}
    for name, (log, robot) in samples_read.items():
        out[name] = map_outputs(log, robot, tmp_path_factory.mktemp(name.replace(".", "_")))
    return out


def test_every_format_gives_the_same_canonical_dump(dumps: dict[str, str]) -> None:
    reference = dumps[SAMPLE_LOGS[0]]
    for name, dump in dumps.items():
        same = dump == reference
        assert same, first_difference(name, dump, reference)
    # what the dump holds: 16 sonars, both tracks, every reading the sync kept
    lines = reference.splitlines()
    assert lines[1] == "sensors 16"
    assert lines[18] == "sync total 23488 used 23460 outside_odometry 0 below_min_range 28"
    assert lines[19] == "poses 1468  # stamp_ns x_m y_m theta_rad"
    assert lines[19 + 1469] == "truth 1468  # stamp_ns x_m y_m theta_rad"
    assert len(lines) == 1 + 17 + 1 + 2 * 1469 + 1 + 23460


def test_the_canonical_dump_is_the_golden_one(dumps: dict[str, str]) -> None:
    dump = dumps[SAMPLE_LOGS[0]]
    head = "".join(dump.splitlines(keepends=True)[:HEAD_LINES])
    golden_head = DUMP_HEAD.read_text(encoding="utf-8")
    assert head == golden_head, f"the dump's head differs from {DUMP_HEAD.name}: {REGENERATE}"
    assert sha256(dump.encode()) == read_sums()[DUMP_NAME], (
        f"the canonical dump differs from its golden SHA-256 (head unchanged): {REGENERATE}"
    )


def test_the_goldens_cover_every_map_output(maps: dict[str, dict[str, bytes]]) -> None:
    outputs = set(maps[SAMPLE_LOGS[0]])
    assert set(read_sums()) == {DUMP_NAME} | outputs
    assert outputs >= {"map.pgm", "map.yaml", "trinary.png", "scale.png", "raw.png", "map.mcap"}


@pytest.mark.parametrize(
    "output", ["map.pgm", "map.yaml", "trinary.png", "scale.png", "raw.png", "map.mcap"]
)
def test_every_format_builds_the_golden_map(maps: dict[str, dict[str, bytes]], output: str) -> None:
    golden = read_sums()[output]
    for name in SAMPLE_LOGS:
        assert maps[name][output] == maps[SAMPLE_LOGS[0]][output], f"{name}: {output} differs"
    assert sha256(maps[SAMPLE_LOGS[0]][output]) == golden, (
        f"{output} built from the samples differs from its golden SHA-256: {REGENERATE}"
    )
    assert len(maps[SAMPLE_LOGS[0]][output]) > (100 if output.endswith(".yaml") else 1000)


def readme_first_example() -> list[str]:
    """The first gridmap command of the README's Use section, split into words."""
    text = (SAMPLES.parent / "README.md").read_text(encoding="utf-8")
    block = text.split("\n## Use\n", 1)[1].split("```sh\n", 1)[1]
    first = next(line for line in block.splitlines() if line.startswith("gridmap "))
    return shlex.split(first.split("#", 1)[0])


def test_the_readme_command_writes_the_golden_map(tmp_path: Path) -> None:
    """`gridmap build samples/corridor_loop.mcap -o out/map.png`, the README's first example
    (with --force, so that the Use block runs twice)."""
    words = readme_first_example()
    assert words[:5] == ["gridmap", "build", "samples/corridor_loop.mcap", "-o", "out/map.png"]
    assert words[5:] in ([], ["--force"])
    out = tmp_path / f"{RUN}.png"
    code, _, err = run("build", str(SAMPLES.parent / words[2]), "-o", str(out), "-q")
    assert code == 0, err
    assert out.read_bytes() == (GOLDEN / f"{RUN}.png").read_bytes(), REGENERATE
    yaml_text = out.with_suffix(".yaml").read_text(encoding="utf-8")
    assert yaml_text == (GOLDEN / f"{RUN}.yaml").read_text(encoding="utf-8"), REGENERATE
    assert yaml_text.startswith(f"image: {RUN}.png\nmode: trinary\nresolution: 0.05\n")


def test_the_cli_writes_the_golden_mcap_map(tmp_path: Path) -> None:
    out = tmp_path / "map.mcap"
    code, _, err = run("build", str(SAMPLES / "corridor_loop.csv"), "-o", str(out), "-q")
    assert code == 0, err
    assert sha256(out.read_bytes()) == read_sums()["map.mcap"], REGENERATE


@pytest.mark.parametrize("source", SAMPLE_LOGS)
def test_convert_to_every_other_format_keeps_the_dump(
    source: str, tmp_path: Path, dumps: dict[str, str]
) -> None:
    """`gridmap convert` from each sample to each other format reads back to the golden dump."""
    assert sorted(STORED_AS) == sorted(SAMPLE_LOGS)
    reference = dumps[SAMPLE_LOGS[0]]
    assert sha256(reference.encode()) == read_sums()[DUMP_NAME], REGENERATE
    targets = [t for t in STORED_AS.values() if t != STORED_AS[source]]
    assert len(targets) == 3
    for fmt, encoding in targets:
        out = tmp_path / f"to_{encoding or fmt}{SUFFIX[fmt]}"
        extra = ["--encoding", encoding] if encoding else []
        code, _, err = run("convert", str(SAMPLES / source), str(out), *extra, "-q")
        assert code == 0, err
        log = read_log(out)
        dump = canonical_dump(log, log_robot(log))
        same = dump == reference
        assert same, first_difference(f"{source} -> {out.name}", dump, reference)


@pytest.fixture(scope="module")
def laser_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short laser + sonar run (p3at-lms200) stored as CSV; thousands of its beams see nothing."""
    loaded = load_map(SAMPLES / "worlds" / "corridor_loop.yaml")
    log = simulate(
        World(loaded.occupied_mask(), loaded.spec),
        parse_path_yaml(PATH, "inline.yaml"),
        load_robot("p3at-lms200"),
        seed=2,
        duration_s=20.0,
    )
    log.metadata["robot"] = "p3at-lms200"
    path = tmp_path_factory.mktemp("laser") / "laser.csv"
    save_csv_log(log, path)
    return path


def test_laser_no_echo_beams_survive_the_aria_format(laser_csv: Path, tmp_path: Path) -> None:
    """CSV -> .2d (`gridmap convert`) keeps every laser beam, no echo included: the .2d carries
    the laser's range (sick1minRange/sick1maxRange) and writes no echo as the maximum range,
    where it used to write ARIA's 0 ("no reading"), which the reader then dropped."""
    aria = tmp_path / "laser.2d"
    code, _, err = run("convert", str(laser_csv), str(aria), "-q")
    assert code == 0, err
    assert "sick1minRange: 0\nsick1maxRange: 8000\n" in aria.read_text(encoding="ascii")
    a, b = read_log(laser_csv), read_log(aria)
    robot = log_robot(a)
    laser = [i for i, n in enumerate(a.sensor_names) if n.startswith("laser1_")]
    no_echo = np.isin(a.readings.sensor, laser) & (a.readings.range_m >= 8.0)
    assert no_echo.sum() > 2000  # the run has plenty of them
    assert len(b.readings) == len(a.readings)
    dump = canonical_dump(b, robot)
    reference = canonical_dump(a, robot)
    assert dump == reference, first_difference("laser.2d", dump, reference)
    images = []
    for log in (a, b):
        result = build_map(log, robot, BuildOptions())
        image, _ = write_map(tmp_path / f"{len(images)}.pgm", result.map, mode="trinary")
        images.append(image.read_bytes())
    assert images[0] == images[1]
