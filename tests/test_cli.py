"""The command line as a user meets it: outputs, summaries, and one-line errors with exit codes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from gridmap_cli.cli import cli
from gridmap_cli.robot import preset_names
from tests.helpers import names, run


def test_build_writes_png_and_yaml(room_csv: Path, tmp_path: Path) -> None:
    out = tmp_path / "maps" / "room.png"
    out.parent.mkdir()
    code, stdout, stderr = run("build", str(room_csv), "-o", str(out))
    assert code == 0, stderr
    meta = yaml.safe_load((out.parent / "room.yaml").read_text())
    assert meta["image"] == "room.png"
    assert meta["resolution"] == 0.05 and meta["origin"][2] == 0.0
    assert meta["occupied_thresh"] == 0.65 and meta["free_thresh"] == 0.196
    assert stdout == ""
    assert "3,200 of 3,200 readings mapped" in stderr and str(out) in stderr
    assert names(out.parent) == {"room.png", "room.yaml"}


def test_build_json_summary(room_csv: Path, tmp_path: Path) -> None:
    out = tmp_path / "room.pgm"
    code, stdout, stderr = run("build", str(room_csv), "-o", str(out), "--json", "--quiet")
    assert code == 0 and stderr == ""
    summary = json.loads(stdout)
    assert summary["readings"] == {
        "total": 3200,
        "used": 3200,
        "skipped": 0,
        "outside_odometry": 0,
        "below_min_range": 0,
    }
    m = summary["map"]
    # the room is 4 m wide; the map must cover it but not be much larger
    assert 4.0 <= m["width"] * m["resolution"] <= 6.0
    assert summary["cells"]["occupied"] > 0 and summary["cells"]["free"] > 0
    assert out.read_bytes().startswith(f"P5\n{m['width']} {m['height']}\n255\n".encode())


def test_walls_land_where_the_room_is(room_csv: Path, tmp_path: Path) -> None:
    from gridmap_cli.mapping.mapfile import load_map

    out = tmp_path / "room.png"
    assert run("build", str(room_csv), "-o", str(out), "--quiet")[0] == 0
    loaded = load_map(tmp_path / "room.yaml")
    spec = loaded.spec
    occ = loaded.occupancy
    import numpy as np

    rows, cols = np.nonzero(occ == 100)
    x, y = spec.cell_center(cols, rows)
    # occupied cells lie near the walls at |x| = 2 or |y| = 2, never in the middle of the room
    assert np.all(np.maximum(np.abs(x), np.abs(y)) > 1.7)
    centre_r, centre_c = spec.world_to_cell(np.array([0.6]), np.array([0.6]))
    assert occ[centre_r[0], centre_c[0]] == 0


BAD = [
    ("time,x,y,theta,sonar0\n0,0,zero,0,1\n", 1, ":2: column 'y': not a number: 'zero'"),
    ("x,y,theta,sonar0\n0,0,0,1\n", 1, ":1: missing required column 'time'"),
    (
        "time,x,y,theta,sonar0\n1,0,0,0,1\n0.5,0,0,0,1\n",
        1,
        ":3: column 'time': time goes backwards",
    ),
    ("time,x,y,theta,sonar0\n0,nan,0,0,1\n", 1, ":2: column 'x': pose must be finite"),
    ("time,x,y,theta,sonar0\n0,0,0,0,1\n1,0,0", 1, ":3: expected 5 fields, found 3"),
    ("time,x,y,theta,sonar0\n0,0,0,0,1\n1,1e12,0,0,1\n", 1, "more than 100000000 cells"),
    ("time,x,y,theta,sonar0\n0,0,0,0,0.01\n", 1, "below their sensor's minimum range"),
]


@pytest.mark.parametrize(("text", "code", "message"), BAD)
def test_bad_logs_give_one_line_and_no_output(
    tmp_path: Path, text: str, code: int, message: str
) -> None:
    log = tmp_path / "bad.csv"
    log.write_text(text)
    out = tmp_path / "out" / "map.png"
    out.parent.mkdir()
    got, _, stderr = run("build", str(log), "-o", str(out), "--robot", "p3dx")
    assert got == code
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: "), stderr
    assert message in lines[0]
    if ":" in message[:3]:
        assert lines[0].startswith(f"Error: {log}{message.split(':')[0]}:")
    assert names(out.parent) == set(), "nothing may be written for bad input"


def test_missing_log(tmp_path: Path) -> None:
    code, _, stderr = run("build", str(tmp_path / "nope.csv"), "-o", str(tmp_path / "m.png"))
    assert code == 1 and stderr.strip() == f"Error: {tmp_path / 'nope.csv'}: no such file"
    assert names(tmp_path) == set()


def test_unknown_robot_is_a_usage_error(room_csv: Path, tmp_path: Path) -> None:
    code, _, stderr = run("build", str(room_csv), "-o", str(tmp_path / "m.png"), "--robot", "r2")
    assert code == 2
    assert stderr.strip() == (
        f"Error: unknown robot 'r2': not a preset ({', '.join(preset_names())}) and no such file"
    )
    assert names(tmp_path) == {"room.csv"}


def test_existing_output_needs_force(room_csv: Path, tmp_path: Path) -> None:
    out = tmp_path / "m.png"
    out.write_bytes(b"keep me")
    code, _, stderr = run("build", str(room_csv), "-o", str(out))
    assert code == 1 and "exists (use --force to overwrite)" in stderr
    assert out.read_bytes() == b"keep me" and not (tmp_path / "m.yaml").exists()
    code, _, _ = run("build", str(room_csv), "-o", str(out), "--force", "-q")
    assert code == 0 and out.read_bytes().startswith(b"\x89PNG")


def test_existing_yaml_alone_also_needs_force(room_csv: Path, tmp_path: Path) -> None:
    (tmp_path / "m.yaml").write_text("keep")
    code, _, stderr = run("build", str(room_csv), "-o", str(tmp_path / "m.png"))
    assert code == 1 and "m.yaml exists" in stderr
    assert not (tmp_path / "m.png").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--occupied", "0.2", "--free", "0.3"], "need 0 <= --free < --occupied <= 1"),
        (["--resolution", "0"], "--resolution must be a positive number of metres"),
        (["--resolution", "nan"], "--resolution must be a positive number of metres, got nan"),
        (["--resolution", "inf"], "--resolution must be a positive number of metres, got inf"),
        (["--occupied", "nan"], "need 0 <= --free < --occupied <= 1"),
        (["--no-echo-free", "nan"], "no-echo free range"),
        (["--map-mode", "scale", "-o", "x.pgm"], "scale"),
        (["-o", "x.jpg"], ".jpg"),
    ],
)
def test_usage_errors_exit_2(room_csv: Path, tmp_path: Path, args: list[str], message: str) -> None:
    argv = ["build", str(room_csv), "-o", str(tmp_path / "m.png"), *args]
    argv = [str(tmp_path / a) if a.startswith("x.") else a for a in argv]
    code, _, stderr = run(*argv)
    assert code == 2 and message in stderr and len(stderr.strip().splitlines()) == 1
    assert names(tmp_path) == {"room.csv"}


def test_output_folder_is_made_unless_a_file_is_in_the_way(room_csv: Path, tmp_path: Path) -> None:
    code, _, stderr = run("build", str(room_csv), "-o", str(tmp_path / "no" / "m.png"))
    assert code == 0 and (tmp_path / "no" / "m.png").is_file(), stderr
    code, _, stderr = run("build", str(room_csv), "-o", str(tmp_path / "room.csv" / "m.png"))
    assert code == 1 and "is not a directory" in stderr


def test_debug_shows_the_traceback(tmp_path: Path) -> None:
    result = CliRunner().invoke(
        cli, ["--debug", "build", str(tmp_path / "nope.csv"), "-o", str(tmp_path / "m.png")]
    )
    assert result.exit_code != 0 and result.exception is not None
    assert "no such file" in str(result.exception)


def test_installed_command_smoke(room_csv: Path, tmp_path: Path) -> None:
    exe = Path(sys.executable).with_name("gridmap")
    if not exe.exists():
        pytest.skip("gridmap is not installed in this environment")
    version = subprocess.run([str(exe), "--version"], capture_output=True, text=True, check=True)
    assert version.stdout.startswith("gridmap, version ")
    out = tmp_path / "smoke.png"
    proc = subprocess.run(
        [str(exe), "build", str(room_csv), "-o", str(out)], capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    assert out.exists() and (tmp_path / "smoke.yaml").exists()
    bad = subprocess.run(
        [str(exe), "build", str(tmp_path / "missing.csv"), "-o", str(out)],
        capture_output=True,
        text=True,
    )
    assert (
        bad.returncode == 1 and bad.stderr.startswith("Error: ") and "Traceback" not in bad.stderr
    )


def test_robot_named_in_the_log_resolves_beside_the_log(room_csv: Path, tmp_path: Path) -> None:
    folder = tmp_path / "run"
    folder.mkdir()
    robot = (
        "gridmap-robot: 1\nname: mine\n"
        "defaults: {beam_width_deg: 25, min_range_m: 0.15, max_range_m: 4.335}\nsensors:\n"
        + "".join(
            f"  - {{name: sonar{i}, x_m: 0.0, y_m: 0.0, yaw_deg: {i * 22.5}}}\n" for i in range(16)
        )
    )
    (folder / "bot.yaml").write_text(robot)
    log = folder / "log.csv"
    log.write_text(room_csv.read_text().replace("# robot: p3dx", "# robot: bot.yaml"))
    code, _, stderr = run("build", str(log), "-o", str(tmp_path / "m.png"), "-q")
    assert code == 0, stderr


def test_unknown_robot_in_the_log_is_bad_data(room_csv: Path, tmp_path: Path) -> None:
    room_csv.write_text(room_csv.read_text().replace("# robot: p3dx", "# robot: r2d2"))
    code, _, stderr = run("build", str(room_csv), "-o", str(tmp_path / "m.png"))
    assert code == 1
    assert stderr.strip() == (
        f"Error: {room_csv}: '# robot: r2d2' is neither a preset ({', '.join(preset_names())}) "
        "nor a file "
        "beside the log; give --robot"
    )


def test_pose_global_maps_with_the_logs_reference_track(tmp_path: Path) -> None:
    from scipy import ndimage

    from gridmap_cli.evaluation.metrics import walls_in_map_frame
    from gridmap_cli.mapping.mapfile import load_map

    samples = Path(__file__).resolve().parents[1] / "samples"
    world = load_map(samples / "worlds" / "corridor_loop.yaml")
    near_wall = ndimage.binary_dilation(world.occupied_mask(), iterations=2)

    def on_true_walls(source: str) -> float:
        """Share of the map's occupied cells within 2 cells of a wall, read in the world frame."""
        out = tmp_path / f"{source}.png"
        code, _, stderr = run(
            "build", str(samples / "corridor_loop.csv"), "-o", str(out), "--pose", source, "-q"
        )
        assert code == 0, stderr
        m = load_map(out.with_suffix(".yaml"))
        # the map read as if its frame were the world's
        on_wall = walls_in_map_frame(m.spec, world.spec, near_wall)
        occupied = m.occupancy == 100
        return float((occupied & on_wall).sum() / occupied.sum())

    # the truth is in the world frame: walls mapped with it land on the world's walls; the
    # odometry map is in the odometry frame (and drifted), so it does not
    assert on_true_walls("global") > 0.6
    assert on_true_walls("odometry") < 0.2


def test_pose_global_needs_a_global_track(room_csv: Path, tmp_path: Path) -> None:
    code, _, stderr = run("build", str(room_csv), "-o", str(tmp_path / "m.png"), "--pose", "global")
    assert code == 1
    assert stderr.strip() == (
        f"Error: {room_csv}: the log has no ground truth (CSV true_x, true_y, true_theta "
        "columns, ARIA robotGlobal: lines in every block, a CARMEN log's TRUEPOS lines or "
        "corrected poses, or a ROS recording's reference: --pose-topic, a ground_truth topic, TF "
        "map -> base or /amcl_pose); --pose global maps with it"
    )
    assert not (tmp_path / "m.png").exists()


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("robot: 40 0 0", "robot: 40 0", "robot: expected 3 numbers, found 2"),
        ("logTime: 0.2", "logTime: 0.05", "time goes backwards"),
        ("sonar: 460 1200", "sonar: 460 12O0", "sonar: not a number: '12O0'"),
    ],
)
def test_malformed_aria_log_exits_1_with_path_line_and_no_output(
    tmp_path: Path, old: str, new: str, message: str
) -> None:
    good = (
        "LaserOdometryLog\nversion: 4\nsonarUnit: 0 147 136 90\nsonarUnit: 1 193 119 50\n"
        "logTime: 0.1\nrobot: 0 0 0\nsonar: 500 4335\nlogTime: 0.2\nrobot: 40 0 0\n"
        "sonar: 460 1200\n"
    )
    log = tmp_path / "run.2d"
    log.write_text(good.replace(old, new))
    out = tmp_path / "out"
    out.mkdir()
    code, _, stderr = run("build", str(log), "-o", str(out / "map.png"))
    line = good.split("\n").index(old) + 1
    assert code == 1
    assert stderr.startswith(f"Error: {log}:{line}: ") and message in stderr
    assert len(stderr.strip().splitlines()) == 1
    assert list(out.iterdir()) == []
    log.write_text(good)
    assert run("build", str(log), "-o", str(out / "map.png"), "-q")[0] == 0
