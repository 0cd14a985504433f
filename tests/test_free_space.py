"""The free-space check (:mod:`gridmap_cli.poses.correction.free_space`): a track whose revisits put
one visit's walls in the free space the other saw fails it, a consistent one does not; and the
automatic pose choice acts on it with a one-line warning."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.poses.correction import free_space as fs
from gridmap_cli.records import PoseTrack
from tests.helpers import run, simulated_laser_log


def _corridor_scan() -> np.ndarray:
    """The echoes (robot frame, facing +x, in the middle) of a corridor 2 m wide whose end wall
    is 6 m ahead, beams every degree over the front half circle."""
    out = []
    for b in np.radians(np.arange(-89.0, 90.0, 1.0)):
        side = 1.0 / abs(math.sin(b)) if abs(math.sin(b)) > 1e-9 else math.inf
        r = min(side, 6.0 / math.cos(b))
        out.append((r * math.cos(b), r * math.sin(b)))
    return np.array(out)


def _shares(second_pose: tuple[float, float, float]) -> float:
    scan = _corridor_scan()
    xyz = np.array([[0.0, 0.0, 0.0], second_pose])
    table = fs.polar([scan, scan])
    return float(fs.pair_shares(np.array([[0, 1]]), xyz, [scan, scan], table)[0, 0])


def test_a_visit_placed_where_it_was_agrees_and_one_turned_across_contradicts() -> None:
    # the same corridor seen twice from the same place: the walls agree
    assert _shares((0.0, 0.0, 0.0)) == 0.0
    # placed turned by 30 degrees, its walls cross the corridor the first visit saw free
    assert _shares((0.5, 0.0, math.radians(30.0))) > 0.3


def test_something_seen_once_contradicts_one_way_only() -> None:
    first = _corridor_scan()
    # the second visit sees a person standing in the corridor 3 m ahead: its echoes there lie
    # in the first visit's free space, while the first's walls stay behind the person
    person = np.array([[3.0, y] for y in np.arange(-0.2, 0.21, 0.05)])
    ahead = np.abs(np.arctan2(first[:, 1], first[:, 0])) > math.radians(6.0)
    second = np.vstack([first[ahead], person])
    xyz = np.zeros((2, 3))
    table = fs.polar([first, second])
    one = fs.one_way(np.array([0]), np.array([1]), xyz, [first, second], table)
    assert one[0, 1] == len(person)  # one way: every echo on the person contradicts
    assert fs.pair_shares(np.array([[0, 1]]), xyz, [first, second], table)[0, 0] == 0.0


def test_a_pair_seen_one_way_only_is_not_judged() -> None:
    # the second visit's scan covers a narrow window ahead (the two visits facing apart overlap
    # at their edges only) with a person in it: its echoes there contradict the first visit,
    # but the first's echoes in that window are too few to tell whether the first's walls stand
    # behind the person, so the pair cannot be told from something that came or went
    first = _corridor_scan()
    bearings = np.radians(np.arange(-6.0, 6.01, 0.5))
    second = (
        np.column_stack([np.cos(bearings), np.sin(bearings)])
        * np.where(np.abs(bearings) < math.radians(3.5), 3.0, 6.0 / np.cos(bearings))[:, None]
    )
    xyz = np.zeros((2, 3))
    table = fs.polar([first, second])
    one = fs.one_way(np.array([0]), np.array([1]), xyz, [first, second], table)
    back = fs.one_way(np.array([1]), np.array([0]), xyz, [first, second], table)
    assert one[0, 0] >= fs.MIN_COMPARED and one[0, 1] > 0.3 * one[0, 0]
    assert back[0, 0] < fs.MIN_COMPARED
    assert len(fs.pair_shares(np.array([[0, 1]]), xyz, [first, second], table)) == 0


def _pairs(shares: np.ndarray, compared: float = 80.0) -> np.ndarray:
    return np.column_stack([shares, np.full(len(shares), compared)])


def _check(shares: np.ndarray, near: np.ndarray, compared: float = 80.0) -> fs.FreeSpaceCheck:
    return fs.FreeSpaceCheck(shares, np.full(len(shares), compared), near, near)


def test_the_judgement_needs_more_contradicting_places_than_the_noise_makes() -> None:
    # near pairs: 97 % agree wholly, 3 % leave 4 of their 80 echoes in the other's free space
    near = _pairs(np.concatenate([np.zeros(970), np.full(30, 4 / 80)]))
    noise = np.full(300, 0.02)  # shares of consistent revisits
    ok = _check(noise, near)
    assert ok.level == pytest.approx(0.1)
    assert ok.contradicting == 0 and not ok.fails
    # a loop closed wrongly: a fifth of the revisits put a third of their echoes in free space
    broken = _check(np.concatenate([noise[:240], np.full(60, 0.35)]), near)
    assert broken.contradicting == 60 and broken.fails
    assert "60 of 300 places the robot came back to contradict" in broken.reason()
    # one such place is what a changed world does now and then: no failure
    assert not _check(np.concatenate([noise[:299], [0.35]]), near).fails
    # judged together, every track takes the least noisy near pairs
    noisy = _pairs(np.concatenate([np.zeros(900), np.full(100, 0.2)]))
    together = fs.judged_together({"a": broken, "b": _check(noise, noisy)})
    assert together["b"].noise is near and together["a"].level == pytest.approx(0.1)
    assert _check(noise, noisy).level == pytest.approx(0.4)


def test_a_share_over_fewer_echoes_must_be_larger_to_contradict() -> None:
    near = _pairs(np.concatenate([np.zeros(970), np.full(30, 4 / 80)]))
    # compared on as many echoes as the near pairs, the level is twice their tail
    assert fs.tail_at(near, np.array([80.0]))[0] == pytest.approx(4 / 80)
    assert _check(np.array([9 / 80]), near).contradicting == 1
    # over 24 echoes (two visits facing apart), three of them in free space is a share the
    # near pairs give more than once in a hundred when cut to 24 echoes: not a contradiction
    assert fs.tail_at(near, np.array([24.0]))[0] == pytest.approx(2 / 24)
    assert _check(np.array([3 / 24]), near, 24.0).contradicting == 0
    assert _check(np.array([6 / 24]), near, 24.0).contradicting == 1
    # each near pair cut to 24 of its 80 echoes, drawn at random: the tail the rule uses
    rng = np.random.default_rng(5)
    drawn = [
        rng.permutation(np.arange(80) < round(s * 80))[:24].mean()
        for s in near[:, 0]
        for _ in range(20)
    ]
    assert np.quantile(drawn, 0.99, method="inverted_cdf") == pytest.approx(2 / 24)


def test_the_judgement_is_the_binomial_tail_of_the_contradicting_places() -> None:
    """A track fails from the first count of contradicting places that consistent revisits
    (each contradicting by chance with probability 1 - TAIL_QUANTILE) reach less often than
    SIGNIFICANCE: the tail summed term by term here."""
    n, chance = 300, 1.0 - fs.TAIL_QUANTILE
    near = _pairs(np.concatenate([np.zeros(970), np.full(30, 4 / 80)]))
    noise = np.full(n, 0.02)
    verdicts = []
    for k in range(25):
        check = _check(np.concatenate([noise[: n - k], np.full(k, 0.35)]), near)
        assert check.contradicting == k
        tail = 1.0 - sum(math.comb(n, i) * chance**i * (1 - chance) ** (n - i) for i in range(k))
        assert abs(tail - fs.SIGNIFICANCE) > 1e-6  # no count sits on the threshold
        verdicts.append(check.fails)
        assert check.fails == (tail < fs.SIGNIFICANCE)
    assert not verdicts[0] and verdicts[-1]  # both verdicts are reached


@pytest.fixture(scope="module")
def laser_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulated_laser_log(tmp_path_factory.mktemp("free"))


def _turned_half(track: PoseTrack, degrees: float) -> PoseTrack:
    """``track`` with its second half turned by ``degrees`` about the pose in its middle."""
    h = len(track.x_m) // 2
    cx, cy = track.x_m[h], track.y_m[h]
    a = math.radians(degrees)
    x, y = track.x_m.copy(), track.y_m.copy()
    x[h:] = cx + math.cos(a) * (track.x_m[h:] - cx) - math.sin(a) * (track.y_m[h:] - cy)
    y[h:] = cy + math.sin(a) * (track.x_m[h:] - cx) + math.cos(a) * (track.y_m[h:] - cy)
    theta = track.theta_rad.copy()
    theta[h:] += a
    return dataclasses.replace(track, x_m=x, y_m=y, theta_rad=theta)


def test_the_graphs_track_passes_and_a_broken_one_fails(laser_log: Path) -> None:
    from gridmap_cli.poses.correction.slam import slam_log
    from gridmap_cli.readers import read_logs
    from gridmap_cli.readers.options import ReadOptions
    from gridmap_cli.robot import robot_from_log

    log = read_logs((laser_log,), None, ReadOptions())
    result = slam_log(log, robot_from_log(laser_log, log.metadata))
    assert result.scans is not None
    points = result.scans.points
    good = fs.check_poses(result.track, points)
    assert good.revisits >= 20 and not good.fails, good
    broken = fs.check_poses(_turned_half(result.track, 5.0), points)
    assert broken.fails and broken.contradicting > 5 * max(good.contradicting, 1), broken
    # the drifting odometry's revisits contradict too
    assert fs.check_poses(result.scan_matched.odometry, points).fails
    # the verdict build warns by: the graph's track passes both looks and says nothing; the
    # broken one is warned of by the check itself, the wide look not taken
    check, wide, said = fs.verdict(result.track, points)
    assert not check.fails and wide is not None and not wide.fails and said is None
    check, wide, said = fs.verdict(_turned_half(result.track, 5.0), points)
    assert check.fails and wide is None and said == check.reason()
    # how the graph ranks the two when it searches wider: passing both first
    from gridmap_cli.poses.correction.repair import PASSES, standing

    assert standing(result.track, points, good) == PASSES
    assert standing(_turned_half(result.track, 5.0), points, broken) == (2, broken.share)


def _broken_slam(monkeypatch: pytest.MonkeyPatch, all_tracks: bool = False) -> None:
    """Make the pose graph return its track with the second half turned by 5 degrees; with
    ``all_tracks``, its scan-matched and odometry tracks turned alike."""
    from gridmap_cli.poses.correction import slam

    solve = slam.slam_log

    def broken(*args: object, **kwargs: object) -> slam.SlamResult:
        result = solve(*args, **kwargs)  # type: ignore[arg-type]
        turned = _turned_half(result.track, 5.0)
        match = dataclasses.replace(result.match, track=turned)
        # the graph's check was of the track as it was: the build checks the turned one
        result = dataclasses.replace(result, match=match, free_space=None)
        if all_tracks:
            matched = dataclasses.replace(result.scan_matched, track=turned, odometry=turned)
            result = dataclasses.replace(result, scan_matched=matched)
        return result

    monkeypatch.setattr(slam, "slam_log", broken)


def test_a_broken_graph_track_falls_back_with_one_warning_line(
    laser_log: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _broken_slam(monkeypatch)
    out = tmp_path / "auto.png"
    code, stdout, stderr = run("build", str(laser_log), "-o", str(out), "--json")
    assert code == 0, stderr
    summary = json.loads(stdout)
    choice = summary["pose_choice"]
    assert choice["source"] == "scan-matched", (choice, stderr)
    assert choice["because"] == "the pose graph's track failed its free-space check"
    checks = summary["free_space_check"]
    assert checks["slam"]["fails"] and not checks["scan-matched"]["fails"], checks
    lines = [line for line in stderr.splitlines() if line.startswith("Warning:")]
    assert len(lines) == 1, stderr
    assert lines[0].startswith(
        "Warning: --pose auto: the pose graph's track fails its free-space check: "
    )
    assert "mapped with the scan-matched track instead" in lines[0]
    # --pose slam keeps the graph's track and says the map may be broken
    code, stdout, stderr = run("build", str(laser_log), "-o", str(tmp_path / "s.png"),
                               "--pose", "slam", "--json")  # fmt: skip
    assert code == 0
    assert json.loads(stdout)["slam"]["free_space_check"]["fails"]
    assert "places the robot came back to contradict the first visit" in stderr
    assert "check the map" in stderr


def test_a_broken_graph_track_is_kept_with_a_warning_when_nothing_does_better(
    laser_log: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _broken_slam(monkeypatch, all_tracks=True)  # the other tracks are as broken
    code, stdout, stderr = run("build", str(laser_log), "-o", str(tmp_path / "a.png"), "--json")
    assert code == 0, stderr
    summary = json.loads(stdout)
    assert summary["pose_choice"]["source"] == "slam"
    checks = summary["free_space_check"]
    assert all(c["fails"] for c in checks.values()), checks
    lines = [line for line in stderr.splitlines() if line.startswith("Warning:")]
    assert len(lines) == 1, stderr
    assert "kept it, no other track does better" in lines[0] and "check the map" in lines[0]


def test_the_wide_look_meets_a_second_pass_drawn_beside_the_first() -> None:
    """Out along y = 0 and back along y = 1.5: the passes never come within a metre, and
    within two metres all along."""
    x = np.concatenate([np.arange(0.0, 20.0, 0.5), np.arange(20.0, 0.0, -0.5)])
    y = np.concatenate([np.zeros(40), np.full(40, 1.5)])
    xyz = np.column_stack([x, y, np.zeros(80)])
    assert len(fs.revisit_pairs(xyz)) == 0
    wide = fs.revisit_pairs(xyz, fs.WIDE_M)
    assert len(wide) >= 30
    assert np.all(wide[:, 0] < 40) and np.all(wide[:, 1] >= 40)
    # near pairs reach as far: each node with the next four
    assert len(fs.near_pairs(10, 4)) == 9 + 8 + 7 + 6


def test_a_pass_drawn_beside_the_first_is_warned_of(
    laser_log: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A track whose second half lies 1.5 m to the side, the graph's own check passing (as it
    does where the passes never meet within a metre): build warns, and maps with it."""
    from gridmap_cli.poses.correction import slam

    solve = slam.slam_log

    def beside(*args: object, **kwargs: object) -> slam.SlamResult:
        result = solve(*args, **kwargs)  # type: ignore[arg-type]
        h = len(result.track.x_m) // 2
        y = result.track.y_m.copy()
        y[h:] += 1.5
        moved = dataclasses.replace(result.track, y_m=y)
        return dataclasses.replace(result, match=dataclasses.replace(result.match, track=moved))

    monkeypatch.setattr(slam, "slam_log", beside)
    code, stdout, stderr = run("build", str(laser_log), "-o", str(tmp_path / "s.png"),
                               "--pose", "slam", "--json")  # fmt: skip
    assert code == 0, stderr
    summary = json.loads(stdout)["slam"]
    assert not summary["free_space_check"]["fails"]
    assert summary["free_space_check_wide"]["fails"]
    (line,) = [w for w in stderr.splitlines() if "come within 2 m" in w]
    assert line.startswith("Warning: --pose slam: where its passes come within 2 m of each other")
    assert line.endswith("check the map")


def test_a_check_whose_near_pairs_disagree_says_it_cannot_judge() -> None:
    # near pairs as a track whose scan matching failed leaves them: one in ten puts 30 % of
    # its echoes in the other's free space, so the level is twice that
    near = _pairs(np.concatenate([np.zeros(900), np.full(100, 0.3)]))
    blind = _check(np.full(50, 0.4), near)
    assert blind.level == pytest.approx(0.6)
    # revisits with 40 % of their echoes in free space, a loop closed wrongly, go unseen
    assert blind.contradicting == 0 and not blind.fails
    assert blind.blind and blind.as_dict()["blind"]
    assert "cannot judge the track" in blind.blindness()
    assert "over 60 % of its echoes" in blind.blindness()
    # the near pairs of a consistent track leave the check its sight
    seeing = _check(np.full(50, 0.4), _pairs(np.concatenate([np.zeros(990), np.full(10, 0.1)])))
    assert not seeing.blind and seeing.fails


def test_a_track_whose_scans_near_in_time_disagree_is_warned_of(
    laser_log: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every scan of the graph's track thrown off its neighbours (as a scan matcher failing
    between sparse scans leaves them): the check cannot judge, and build says so."""
    from gridmap_cli.poses.correction import slam

    solve = slam.slam_log

    def scattered(*args: object, **kwargs: object) -> slam.SlamResult:
        result = solve(*args, **kwargs)  # type: ignore[arg-type]
        t = result.track
        rng = np.random.default_rng(3)
        off = rng.normal(0.0, 1.0, (len(t.x_m), 3)) * (0.5, 0.5, math.radians(20.0))
        moved = dataclasses.replace(
            t, x_m=t.x_m + off[:, 0], y_m=t.y_m + off[:, 1], theta_rad=t.theta_rad + off[:, 2]
        )
        match = dataclasses.replace(result.match, track=moved)
        return dataclasses.replace(result, match=match, free_space=None)

    monkeypatch.setattr(slam, "slam_log", scattered)
    out = tmp_path / "s.png"
    code, stdout, stderr = run("build", str(laser_log), "-o", str(out), "--pose", "slam",
                               "--json")  # fmt: skip
    assert code == 0, stderr
    summary = json.loads(stdout)["slam"]
    assert summary["free_space_check"]["blind"]
    assert not summary["free_space_check"]["fails"]
    (line,) = [w for w in stderr.splitlines() if "cannot judge" in w]
    assert line.startswith("Warning: --pose slam: the free-space check cannot judge the track")
    assert line.endswith("check the map")
    assert out.exists()
