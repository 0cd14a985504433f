"""``gridmap batch`` takes build's map options, defined once: the same flags and help, the same
map bytes as ``gridmap build`` with them, and a key that changes with every one of them (so
``up to date`` is honest)."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import click
import pytest

from gridmap_cli.cli.batch import batch
from gridmap_cli.cli.build import build
from gridmap_cli.cli.map_options import map_options
from gridmap_cli.mapping.models.fading import ErrorAwareParams
from gridmap_cli.mapping.models.ray import RayParams
from gridmap_cli.mapping.models.standard import StandardSonarParams
from gridmap_cli.mapping.pipeline import BuildOptions
from gridmap_cli.poses.odometry_error import OdometryError
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.runs.batch import REPORT_NAME, BatchOptions, job_key
from gridmap_cli.writers.csv_log import save_csv_log
from tests.helpers import run
from tests.test_scan_match import room_world
from tests.test_scan_match import run as simulate_run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


def statuses(outdir: Path) -> dict[str, str]:
    lines = (outdir / REPORT_NAME).read_text().splitlines()
    return {Path(json.loads(line)["log"]).name: json.loads(line)["status"] for line in lines}


def _map_option_names() -> set[str]:
    @click.command()
    @map_options
    def probe(**_: object) -> None:
        """The map options alone."""

    return {p.name for p in probe.params if p.name is not None}


def test_batch_has_every_map_option_of_build_with_the_same_flags_and_help() -> None:
    names = _map_option_names() | {"image_format", "error_samples"}
    assert {"sensor_patterns", "start", "end", "no_echo_free", "pose", "mode"} <= names
    built = {p.name: p for p in build.params}
    batched = {p.name: p for p in batch.params}
    for name in sorted(names - {"image_format"}):
        mine, theirs = batched[name], built[name]
        assert (mine.opts, mine.secondary_opts, mine.default) == (
            theirs.opts, theirs.secondary_opts, theirs.default
        ), name  # fmt: skip
        assert getattr(mine, "help", None) == getattr(theirs, "help", None), name
        assert getattr(mine.type, "choices", None) == getattr(theirs.type, "choices", None), name
    assert batched["image_format"].opts == ["--fmt"]
    assert batched["image_format"].type.choices == built["image_format"].type.choices  # type: ignore[attr-defined]
    pose = batched["pose"]
    assert set(pose.type.choices) >= {"odometry", "global", "scan-matched", "slam"}  # type: ignore[attr-defined]
    assert "scan-matched" in str(getattr(pose, "help", "")) and "slam" in str(
        getattr(pose, "help", "")
    )
    code, help_text, _ = run("batch", "--help")
    assert code == 0
    for flag in ("--fmt", "--sensors", "--no-echo-free", "--start", "--end", "--odom-topic"):
        assert flag in help_text


@pytest.mark.parametrize(
    "options",
    [
        ("--pose", "global", "--sensors", "sonar[0-7]", "--start", "5", "--end", "90",
         "--no-echo-free", "0.5", "--resolution", "0.1"),
        ("--mode", "error-aware", "--odometry-coefficient", "range_m_per_m=0.02",
         "--map-mode", "raw", "--resolution", "0.1", "--error-samples", "4"),
    ],
    ids=["selection", "error-aware"],
)  # fmt: skip
def test_batch_with_map_options_writes_builds_bytes(
    tmp_path: Path, options: tuple[str, ...]
) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    shutil.copy(SAMPLES / "hall.csv", logs / "hall.csv")
    out = tmp_path / "maps"
    code, _, err = run("batch", str(logs), "-o", str(out), "--fmt", "pgm", *options)
    assert code == 0, err
    assert not (out / "hall.png").exists()
    built = tmp_path / "hall.pgm"
    assert run("build", str(logs / "hall.csv"), "-o", str(built), "-q", *options)[0] == 0
    assert (out / "hall.pgm").read_bytes() == built.read_bytes()
    # and the options changed the map: the default build is another one
    plain = tmp_path / "plain.pgm"
    assert run("build", str(logs / "hall.csv"), "-o", str(plain), "-q")[0] == 0
    assert plain.read_bytes() != built.read_bytes()


def test_batch_correct_odometry_is_builds(tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    shutil.copy(SAMPLES / "hall.csv", logs / "hall.csv")
    odometry = tmp_path / "odometry.yaml"  # its signed biases, as calibrate fits them
    assert run("calibrate", str(logs / "hall.csv"), "-o", str(odometry), "-q")[0] == 0
    options = ("--odometry-error", str(odometry), "--correct-odometry")
    code, _, err = run("batch", str(logs), "-o", str(tmp_path / "maps"), "-q", *options)
    assert code == 0, err
    built = tmp_path / "hall.png"
    assert run("build", str(logs / "hall.csv"), "-o", str(built), "-q", *options)[0] == 0
    assert (tmp_path / "maps" / "hall.png").read_bytes() == built.read_bytes()
    plain = tmp_path / "plain.png"
    assert run("build", str(logs / "hall.csv"), "-o", str(plain), "-q")[0] == 0
    assert plain.read_bytes() != built.read_bytes()
    # the robot's own odometry only, in batch as in build
    code, _, err = run("batch", str(logs), "-o", str(tmp_path / "g"), "--pose", "global", *options)
    assert code == 2 and "--correct-odometry corrects the robot's own odometry" in err
    assert not (tmp_path / "g").exists()


def test_batch_scan_matched_and_slam_are_builds_maps(tmp_path: Path) -> None:
    log = simulate_run(room_world(), [[2, 1.5], [10, 1.5], [10, 6.5], [2, 6.5], [2, 1.5]],
                       drift=3.0)  # fmt: skip
    log.metadata["robot"] = "p3at-lms200"
    logs = tmp_path / "logs"
    logs.mkdir()
    save_csv_log(log, logs / "room.csv")
    for pose in ("scan-matched", "slam"):
        out = tmp_path / pose
        code, _, err = run("batch", str(logs), "-o", str(out), "--pose", pose, "-q")
        assert code == 0, err
        built = tmp_path / f"{pose}.png"
        code, _, err = run("build", str(logs / "room.csv"), "--pose", pose, "-o", str(built), "-q")
        assert code == 0, err
        assert (out / "room.png").read_bytes() == built.read_bytes(), pose


def test_batch_error_aware_slam_maps_on_the_graphs_uncertainty_as_build_does(
    tmp_path: Path,
) -> None:
    log = simulate_run(room_world(), [[2, 1.5], [10, 1.5], [10, 6.5], [2, 6.5], [2, 1.5]],
                       drift=3.0)  # fmt: skip
    log.metadata["robot"] = "p3at-lms200"
    logs = tmp_path / "logs"
    logs.mkdir()
    save_csv_log(log, logs / "room.csv")
    # no --odometry-error: the pose graph's marginals are the pose uncertainty
    args = ("--pose", "slam", "--mode", "error-aware", "--error-samples", "2",
            "--map-mode", "scale", "-q")  # fmt: skip
    code, _, err = run("batch", str(logs), "-o", str(tmp_path / "out"), *args)
    assert code == 0, err
    built = tmp_path / "built.png"
    code, _, err = run("build", str(logs / "room.csv"), "-o", str(built), *args)
    assert code == 0, err
    plain = tmp_path / "standard.png"
    code, _, err = run("build", str(logs / "room.csv"), "-o", str(plain), "--pose", "slam",
                       "--map-mode", "scale", "-q")  # fmt: skip
    assert code == 0, err
    assert (tmp_path / "out" / "room.png").read_bytes() == built.read_bytes()
    assert built.read_bytes() != plain.read_bytes()


def test_every_option_that_changes_a_map_changes_its_key() -> None:
    base = BatchOptions()
    build = base.build
    variants = [
        dataclasses.replace(base, build=dataclasses.replace(build, resolution_m=0.1)),
        dataclasses.replace(base, build=dataclasses.replace(build, mode="error-aware")),
        dataclasses.replace(
            base, build=dataclasses.replace(build, sonar=StandardSonarParams(no_echo_free_m=0.5))
        ),
        dataclasses.replace(
            base, build=dataclasses.replace(build, error_aware=ErrorAwareParams(0.5))
        ),
        dataclasses.replace(
            base,
            build=dataclasses.replace(
                build, odometry_error=dataclasses.replace(OdometryError(), range_m_per_m=0.02)
            ),
        ),
        dataclasses.replace(base, build=dataclasses.replace(build, error_samples=0)),
        dataclasses.replace(base, build=dataclasses.replace(build, correct_odometry=True)),
        dataclasses.replace(base, build=dataclasses.replace(build, ray=RayParams(max_range_m=8.0))),
        dataclasses.replace(base, robot="p3dx"),
        dataclasses.replace(base, log_format="csv"),
        dataclasses.replace(base, pose="global"),
        dataclasses.replace(base, pose="scan-matched"),
        dataclasses.replace(base, pose="slam"),
        dataclasses.replace(base, topics=ReadOptions(odom_topic="/odom")),
        dataclasses.replace(base, topics=ReadOptions(range_topics=("/scan",))),
        dataclasses.replace(base, topics=ReadOptions(pose_topic="/amcl_pose")),
        dataclasses.replace(base, sensors=("sonar*",)),
        dataclasses.replace(base, start="5"),
        dataclasses.replace(base, end="60"),
        dataclasses.replace(base, map_mode="scale"),
        dataclasses.replace(base, occupied=0.7),
        dataclasses.replace(base, free=0.2),
        dataclasses.replace(base, image_format="pgm"),
    ]
    keys = [job_key("content", o) for o in (base, *variants)]
    assert len(set(keys)) == len(keys)
    assert job_key("content", BatchOptions()) == keys[0]  # the same options, the same key
    # processes mapping one log do not change its map, nor its key
    jobs = dataclasses.replace(base, build=dataclasses.replace(build, jobs=4))
    assert job_key("content", jobs) == keys[0]
    assert job_key("other content", base) != keys[0]
    assert "jobs" not in base.as_dict()["build"]
    assert BuildOptions().resolution_m == base.resolution_m


@pytest.mark.parametrize(
    "changed",
    [("--no-echo-free", "0.5"), ("--sensors", "sonar[0-3]"), ("--start", "10"),
     ("--end", "60"), ("--pose", "global"), ("--occupied", "0.7"), ("--max-range", "3")],
)  # fmt: skip
def test_a_changed_option_rebuilds_and_the_same_one_skips(
    tmp_path: Path, changed: tuple[str, str]
) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    shutil.copy(SAMPLES / "hall.csv", logs / "hall.csv")
    out = tmp_path / "maps"
    assert run("batch", str(logs), "-o", str(out), "-q")[0] == 0
    assert run("batch", str(logs), "-o", str(out), "-q", *changed)[0] == 0
    assert statuses(out) == {"hall.csv": "built"}
    assert run("batch", str(logs), "-o", str(out), "-q", *changed)[0] == 0
    assert statuses(out) == {"hall.csv": "skipped"}


def test_an_edited_robot_file_rebuilds_whether_given_or_named_by_the_log(tmp_path: Path) -> None:
    from gridmap_cli.robot import preset_names  # noqa: F401 - the presets are files too

    preset = Path(__file__).resolve().parents[1] / "gridmap_cli" / "presets" / "p3at.yaml"
    logs = tmp_path / "logs"
    logs.mkdir()
    text = (SAMPLES / "hall.csv").read_text().replace("# robot: p3at", "# robot: mine.yaml", 1)
    (logs / "hall.csv").write_text(text)
    (logs / "mine.yaml").write_text(preset.read_text())
    given = tmp_path / "given.yaml"
    given.write_text(preset.read_text())
    out, out_given = tmp_path / "maps", tmp_path / "given"
    assert run("batch", str(logs), "-o", str(out), "-q")[0] == 0
    assert run("batch", str(logs), "-o", str(out_given), "-q", "--robot", str(given))[0] == 0
    assert run("batch", str(logs), "-o", str(out), "-q")[0] == 0
    assert statuses(out) == {"hall.csv": "skipped"}
    for robot_file in (logs / "mine.yaml", given):
        robot_file.write_text(robot_file.read_text() + "\n# edited\n")
    assert run("batch", str(logs), "-o", str(out), "-q")[0] == 0
    assert statuses(out) == {"hall.csv": "built"}
    assert run("batch", str(logs), "-o", str(out_given), "-q", "--robot", str(given))[0] == 0
    assert statuses(out_given) == {"hall.csv": "built"}


def test_map_option_usage_errors_come_before_any_work(tmp_path: Path) -> None:
    out = tmp_path / "o"
    for args, text in [
        (("--map-mode", "scale", "--fmt", "pgm"), "scale maps need a PNG"),
        (("--sensors", "!"), "empty pattern"),
        (("--start", "60", "--end", "10"), "is not before --end"),
        (("--no-echo-free", "-1"), "no-echo free range"),
        (("--odometry-coefficient", "range_m_per_m=0.1"), "apply to --mode error-aware"),
        (("--mode", "error-aware", "--pose", "odometry"), "needs the odometry error"),
        (("--mode", "trinary"), "--map-mode trinary"),
        (("--free", "0.7"), "--free < --occupied"),
        (("--error-samples", "4"), "--error-samples applies to --mode error-aware"),
    ]:
        code, _, err = run("batch", str(SAMPLES / "hall.csv"), "-o", str(out), *args)
        assert code == 2 and err.count("\n") == 1, (args, err)
        assert text in err, (args, err)
    assert not out.exists()
