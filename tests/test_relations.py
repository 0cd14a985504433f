"""The SLAM benchmark's relations: reading them, scoring a track, and `trajectory --relations`."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.errors import InputFileError
from gridmap_cli.evaluation.relations import (
    find_clock_offset,
    moved_to,
    on_logged_clock,
    printed_step_ns,
    read_relations,
    reordered_on_logged_clock,
    score_track,
)
from gridmap_cli.records import MovedStamps, PoseTrack
from tests.helpers import names, run, simulated_laser_log

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


def _circle(n: int = 50) -> PoseTrack:
    """A robot driving a circle of radius 5 m, one pose a second from t = 100 s."""
    a = np.linspace(0.0, 1.5 * math.pi, n)
    return PoseTrack(
        stamp_ns=(100 + np.arange(n)).astype(np.int64) * 1_000_000_000,
        x_m=5 * np.cos(a),
        y_m=5 * np.sin(a),
        theta_rad=np.asarray((a + math.pi / 2 + math.pi) % (2 * math.pi) - math.pi),
    )


def _relations_of(track: PoseTrack, pairs: list[tuple[int, int]], dx: float = 0.0) -> str:
    lines = []
    for i, j in pairs:
        c, s = math.cos(track.theta_rad[i]), math.sin(track.theta_rad[i])
        ex, ey = track.x_m[j] - track.x_m[i], track.y_m[j] - track.y_m[i]
        rx, ry = c * ex + s * ey, -s * ex + c * ey
        rth = (track.theta_rad[j] - track.theta_rad[i] + math.pi) % (2 * math.pi) - math.pi
        t1, t2 = track.stamp_ns[i] / 1e9, track.stamp_ns[j] / 1e9
        lines.append(f"{t1:.6f} {t2:.6f} {rx + dx:.9f} {ry:.9f} 0 0 0 {rth:.9f}")
    return "\n".join(lines) + "\n"


PAIRS = [(0, 1), (3, 10), (10, 40), (5, 6), (20, 49)]


def test_a_perfect_track_scores_zero() -> None:
    track = _circle()
    score = score_track(track, read_relations(io.StringIO(_relations_of(track, PAIRS))))
    assert score.count == 5 and score.skipped == 0
    assert score.trans_mean_m == pytest.approx(0.0, abs=1e-6)
    assert score.rot_mean_deg == pytest.approx(0.0, abs=1e-5)


def test_a_known_offset_scores_that_offset() -> None:
    track = _circle()
    score = score_track(track, read_relations(io.StringIO(_relations_of(track, PAIRS, dx=0.25))))
    assert score.trans_mean_m == pytest.approx(0.25, abs=1e-6)
    assert score.trans_std_m == pytest.approx(0.0, abs=1e-6)


def test_a_clock_offset_shifts_the_relations_onto_the_track() -> None:
    track = _circle()
    text = _relations_of(track, PAIRS)
    shifted = "\n".join(
        " ".join([f"{float(v) + 1000:.6f}" if k < 2 else v for k, v in enumerate(line.split())])
        for line in text.splitlines()
    )
    relations = read_relations(io.StringIO(shifted))
    assert score_track(track, relations).count == 0
    score = score_track(track, relations, offset_s=1000.0)
    assert score.count == 5 and score.trans_mean_m == pytest.approx(0.0, abs=1e-5)


def test_a_stamp_between_poses_is_moved_on_by_the_odometry() -> None:
    # the track has a pose every 2 s; the relation's stamps fall between them (1 s away, beyond
    # 0.1 s): the odometry, here the full 1 Hz circle, carries the nearest pose to the stamp
    full = _circle()
    sparse = PoseTrack(full.stamp_ns[::2], full.x_m[::2], full.y_m[::2], full.theta_rad[::2])
    relations = read_relations(io.StringIO(_relations_of(full, [(1, 9), (3, 27)])))
    assert score_track(sparse, relations, full).trans_mean_m == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("1 2 0 0 0 0 0 0\n1 2 3\n", "<relations>:2: expected 8 fields"),
        ("# header\n1 2 0 0 0 0 0 x\n", "<relations>:2: not a number: 'x'"),
        ("1 2 0 0 0 0 0 nan\n", "<relations>:1: values must be finite"),
        ("\n", "<relations>: holds no relation"),
    ],
)
def test_malformed_lines_name_the_line(text: str, message: str) -> None:
    with pytest.raises(InputFileError) as caught:
        read_relations(io.StringIO(text), "<relations>")
    assert str(caught.value).startswith(message)


def _sample_relations(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "run.relations"
    path.write_text(text)
    return path


def test_trajectory_prints_the_relations_error(tmp_path: Path) -> None:
    log = SAMPLES / "corridor_loop.csv"
    out = tmp_path / "ref.tum"
    code, _, _ = run("trajectory", str(log), "--pose", "global", "-o", str(out))
    assert code == 0
    rows = np.loadtxt(out)
    track = PoseTrack.from_rows(
        np.round(rows[:, 0] * 1e9).astype(np.int64),
        [(r[1], r[2], 2 * math.atan2(r[6], r[7])) for r in rows],
    )
    rel = _sample_relations(tmp_path, _relations_of(track, [(0, 10), (10, 50), (30, 31)]))
    out.unlink()
    args = ["trajectory", str(log), "--pose", "global", "-o", str(out), "--relations", str(rel)]
    code, stdout, stderr = run(*args, "--json")
    assert code == 0, stderr
    summary = json.loads(stdout)["relations"]
    assert summary["relations"] == 3 and summary["trans_mean_m"] < 1e-3
    assert "gridmap: relations 3 (skipped 0): translation 0.000 +/- 0.000 m" in stderr


def test_bad_relations_write_nothing(tmp_path: Path) -> None:
    log = SAMPLES / "corridor_loop.csv"
    rel = _sample_relations(tmp_path, "1 2 3\n")
    out = tmp_path / "t.tum"
    code, _, stderr = run("trajectory", str(log), "--pose", "odometry", "-o", str(out),
                          "--relations", str(rel))  # fmt: skip
    assert code == 1 and f"Error: {rel}:1: expected 8 fields" in stderr
    assert names(tmp_path) == {"run.relations"}
    rel.write_text("1e6 1.1e6 0 0 0 0 0 0\n")
    code, _, stderr = run("trajectory", str(log), "--pose", "odometry", "-o", str(out),
                          "--relations", str(rel))  # fmt: skip
    assert code == 1 and "no relation lies within the track's time span" in stderr
    assert names(tmp_path) == {"run.relations"}


DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.mark.skipif(not (DATA / "slam-benchmark" / "aces.relations").exists(), reason="no data")
def test_aces_odometry_scores_the_published_figure() -> None:
    from gridmap_cli.poses.sources import pose_source
    from gridmap_cli.readers import read_logs
    from gridmap_cli.readers.options import ReadOptions

    data = read_logs((DATA / "carmen" / "aces-corrected.log.gz",), None, ReadOptions())
    relations = read_relations(DATA / "slam-benchmark" / "aces.relations")
    odometry = pose_source("odometry").run(data, None).log.poses
    score = score_track(odometry, relations, data.poses, offset_s=70.185)
    # the measurement: 0.549 m for the odometry
    assert score.count == len(relations) and score.trans_mean_m == pytest.approx(0.549, abs=0.01)


def test_poses_are_looked_up_by_the_stamps_the_log_gave_them() -> None:
    # the log said 105 s for the pose it printed after 107 s; the reader moved it to 107.001 s
    track = _circle()
    logged = track.stamp_ns.copy()
    repaired = track.stamp_ns.copy()
    repaired[5] = track.stamp_ns[7] + 1_000_000
    order = np.argsort(repaired)
    as_read = PoseTrack(
        stamp_ns=repaired[order],
        x_m=track.x_m[order],
        y_m=track.y_m[order],
        theta_rad=track.theta_rad[order],
    )
    relations = read_relations(io.StringIO(_relations_of(track, [(5, 20), (2, 5)])), "r")
    moved = MovedStamps(stamp_ns=repaired[5:6], logged_ns=logged[5:6])
    on_log = on_logged_clock(as_read, moved)
    np.testing.assert_array_equal(on_log.stamp_ns, logged)
    assert score_track(as_read, relations, moved=moved).trans_mean_m < 1e-6
    # by the moved stamps the ends at 105 s fall between the poses at 104 and 106 s instead
    assert score_track(as_read, relations).trans_mean_m > 0.01


def test_the_printed_step_is_found_per_decade_of_seconds() -> None:
    stamps = np.array(
        [12_345_000, 512_346_000_000, 512_347_000_000, 2_612_410_000_000, 2_612_420_000_000]
    )
    np.testing.assert_array_equal(
        printed_step_ns(stamps), [1_000, 1_000_000, 1_000_000, 10_000_000, 10_000_000]
    )


def test_equal_logged_stamps_are_spread_over_their_printed_step_in_file_order() -> None:
    # four lines printed "2612.41" and one "2612.42" (six significant digits: a 10 ms step)
    logged = np.array([2612.41, 2612.41, 2612.41, 2612.41, 2612.42])
    logged_ns = np.round(logged * 1e9).astype(np.int64)
    repaired = logged_ns[0] + np.arange(5, dtype=np.int64) * 1_000
    repaired[4] = logged_ns[4]
    track = PoseTrack(stamp_ns=repaired, x_m=np.arange(5.0), y_m=np.zeros(5), theta_rad=np.zeros(5))
    moved = MovedStamps(stamp_ns=repaired[1:4], logged_ns=logged_ns[1:4])
    out = on_logged_clock(track, moved)
    np.testing.assert_array_equal(out.x_m, np.arange(5.0))
    offsets_ms = (out.stamp_ns[:4] - logged_ns[0]) / 1e6
    np.testing.assert_allclose(offsets_ms, [-3.75, -1.25, 1.25, 3.75])
    assert out.stamp_ns[4] == logged_ns[4]


def test_trajectory_writes_the_stamps_the_log_gave(tmp_path: Path) -> None:
    """A CARMEN line whose stamp goes back is moved forward by the reader to keep time running;
    the TUM file carries it at the stamp the log printed, as the relations name it."""
    stamps = [0.0, 0.5, 1.0, 0.9, 2.0, 2.5]  # the fourth goes back
    lines = [f"ODOM {0.1 * k:.3f} 0 0 0 0 0 {t:.6f} host {t:.6f}" for k, t in enumerate(stamps)]
    lines += [f"FLASER 3 1.0 1.0 1.0 0 0 0 0 0 0 {t} host {t}" for t in (2.1, 2.2)]
    log = tmp_path / "back.log"
    log.write_text("\n".join(lines) + "\n")
    out = tmp_path / "odo.tum"
    code, _, stderr = run("trajectory", str(log), "--pose", "odometry", "-o", str(out))
    assert code == 0, stderr
    rows = np.loadtxt(out)
    written = dict(zip(np.round(rows[:, 0], 6), rows[:, 1], strict=True))
    assert written[0.9] == pytest.approx(0.3)  # the line printed at 0.9 s, at 0.9 s
    assert set(stamps) <= set(written)


def test_the_logged_clock_order_takes_what_is_written_beside_each_pose_along() -> None:
    track = _circle(8)
    logged = track.stamp_ns.copy()
    logged[3] = logged[1] + 1  # printed before the second pose's neighbour: it goes back
    moved = MovedStamps(stamp_ns=track.stamp_ns[3:4], logged_ns=logged[3:4])
    out, order = reordered_on_logged_clock(track, moved)
    assert list(order[:4]) == [0, 1, 3, 2]
    assert np.array_equal(out.x_m, track.x_m[order])
    assert np.all(np.diff(out.stamp_ns) > 0)


def _random_stamps(n: int, seed: int) -> list[float]:
    """``n`` stamps (s) at random moments of the circle's 50 s, on no pose stamp."""
    rng = np.random.default_rng(seed)
    return sorted(100.0 + rng.uniform(0.0, 49.0, n))


def test_the_clock_offset_is_found_from_the_stamps() -> None:
    track = _circle()
    text = _relations_of(track, PAIRS + [(k, k + 3) for k in range(0, 40, 4)])
    shifted = "".join(
        f"{float(a) + 1234.5:.6f} {float(b) + 1234.5:.6f} {rest}\n"
        for a, b, rest in (line.split(" ", 2) for line in text.splitlines())
    )
    relations = read_relations(io.StringIO(shifted))
    clock = find_clock_offset(track.stamp_ns, relations)
    assert clock.searched and clock.offset_s == pytest.approx(1234.5, abs=1e-6)
    assert "log's + 1234.500 s, found from the stamps" in clock.message()
    score = score_track(track, relations, offset_s=clock.offset_s)
    assert score.count == len(relations) and score.trans_mean_m < 1e-6


def test_relations_on_the_logs_own_clock_need_no_offset() -> None:
    track = _circle()
    relations = read_relations(io.StringIO(_relations_of(track, PAIRS)))
    clock = find_clock_offset(track.stamp_ns, relations)
    assert clock.offset_s == 0.0 and not clock.searched
    assert clock.landed == clock.inside == len({k for pair in PAIRS for k in pair})


def test_stamps_that_land_nowhere_give_no_offset() -> None:
    track = _circle()
    starts, ends = _random_stamps(20, 1), _random_stamps(20, 2)
    relations = read_relations(
        io.StringIO(
            "".join(f"{a:.6f} {b:.6f} 1 0 0 0 0 0\n" for a, b in zip(starts, ends, strict=True))
        )
    )
    clock = find_clock_offset(track.stamp_ns, relations)
    assert clock.offset_s is None and clock.searched
    assert clock.message().endswith(": give --relations-offset")
    assert "\n" not in clock.message()


def test_trajectory_finds_and_says_the_clock_offset(tmp_path: Path) -> None:
    log = SAMPLES / "corridor_loop.csv"
    out = tmp_path / "ref.tum"
    code, _, _ = run("trajectory", str(log), "--pose", "global", "-o", str(out))
    rows = np.loadtxt(out)
    track = PoseTrack.from_rows(
        np.round(rows[:, 0] * 1e9).astype(np.int64),
        [(r[1], r[2], 2 * math.atan2(r[6], r[7])) for r in rows],
    )
    pairs = [(k, k + 7) for k in range(0, len(track) - 7, max(1, len(track) // 40))]
    text = _relations_of(track, pairs)
    shifted = "".join(
        f"{float(a) + 5000.0:.6f} {float(b) + 5000.0:.6f} {rest}\n"
        for a, b, rest in (line.split(" ", 2) for line in text.splitlines())
    )
    rel = _sample_relations(tmp_path, shifted)
    args = ["trajectory", str(log), "--pose", "global", "-o", str(out), "--force"]
    code, stdout, stderr = run(*args, "--relations", str(rel), "--json")
    assert code == 0, stderr
    summary = json.loads(stdout)["relations"]
    assert summary["offset_s"] == pytest.approx(5000.0, abs=1e-6)
    assert summary["relations"] == len(pairs) and summary["trans_mean_m"] < 1e-3
    assert "gridmap: relations: the relations' clock is the log's + 5000.000 s" in stderr
    # an offset given wins, even a wrong one
    code, stdout, stderr = run(*args, "--relations", str(rel), "--relations-offset", "5000.5")
    assert code == 0 and "found from the stamps" not in stderr
    assert "translation 0.000" not in stderr


def test_relations_of_another_point_of_the_robot_score_the_lever_arm() -> None:
    """Relations of a point 0.3 m ahead of the track's: the turning relations are off by
    2 d sin(a/2); the track moved to that point scores zero."""
    track = _circle()
    ahead = moved_to(track, 0.3, 0.0)
    relations = read_relations(io.StringIO(_relations_of(ahead, PAIRS)))
    assert score_track(track, relations).trans_mean_m > 0.05
    assert score_track(ahead, relations).trans_mean_m == pytest.approx(0.0, abs=1e-6)
    np.testing.assert_array_equal(ahead.theta_rad, track.theta_rad)
    assert math.hypot(ahead.x_m[0] - track.x_m[0], ahead.y_m[0] - track.y_m[0]) == (
        pytest.approx(0.3)
    )


def test_trajectory_scores_the_lasers_point_too(tmp_path: Path) -> None:
    """A robot whose laser sits 0.16 m ahead of base_link (p3at-lms200), relations of the
    laser's point: trajectory gives both figures, the laser's near zero."""
    log = simulated_laser_log(tmp_path)
    out = tmp_path / "ref.tum"
    code, _, stderr = run("trajectory", str(log), "--pose", "global", "-o", str(out))
    assert code == 0, stderr
    rows = np.loadtxt(out)
    track = PoseTrack.from_rows(
        np.round(rows[:, 0] * 1e9).astype(np.int64),
        [(r[1], r[2], 2 * math.atan2(r[6], r[7])) for r in rows],
    )
    n = len(rows)
    pairs = [(k, k + n // 3) for k in range(0, n - n // 3, max(1, n // 40))]
    rel = _sample_relations(tmp_path, _relations_of(moved_to(track, 0.16, 0.0), pairs))
    code, stdout, stderr = run("trajectory", str(log), "--pose", "global", "-o", str(out),
                               "--force", "--relations", str(rel), "--json")  # fmt: skip
    assert code == 0, stderr
    scored = json.loads(stdout)["relations"]
    assert scored["trans_mean_m"] > 0.02
    assert scored["at_laser"]["laser_m"] == [0.16, 0.0]
    assert scored["at_laser"]["trans_mean_m"] < 1e-3
    assert "relations of the laser's point (0.16, 0) m from base_link instead" in stderr
