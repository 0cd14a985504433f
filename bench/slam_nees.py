"""Are the pose graph's covariances honest? NEES of the SLAM benchmark's relations (issue 20,
"Uncertainty out"; docs/scan-matching.md, "Uncertainty").

For each shared CARMEN log it runs ``--pose slam``'s pipeline once and, for each ground-truth
relation (``../shared/data/slam-benchmark``), compares the estimated relative pose with the
covariance the graph predicts for it (:mod:`gridmap_cli.evaluation.relation_nees`): NEES, whose
median is 2.37 when the covariances are right. It does so twice: with the graph's hand-set
edge noise (what ``gridmap trajectory`` writes) and with the noise calibrated on the graph's
own residuals (what the error-aware map samples, :func:`~gridmap_cli.poses.uncertainty.pose_belief.
calibrated_graph`).

A relation's ends rarely fall on a kept scan (these logs keep a scan every 0.2-3 s, the
relations sit on the original logs' scans). The estimate there is the nearest scan's pose moved
on by the odometry, as the benchmark's evaluator does; its covariance is the graph's (the scan
attached to its nearer keyframe by the scan-matched offset, with the sequential edges' noise
for that offset) plus the odometry's own noise over the stretch, measured on the same log: the
spread of the odometry's steps between consecutive matched scans against the scan matcher's,
as a random walk per metre (and radian) of motion (median-based). The table says how much of
the predicted variance is the graph's: on ACES hardly any (its scans are 2 s apart and its
relations short), so only Freiburg 079 (scans 0.2 s apart) tests the graph itself.

    .venv/bin/python bench/slam_nees.py                 # the three logs (some 3 minutes)
    .venv/bin/python bench/slam_nees.py --logs freiburg-079
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import gtsam
import numpy as np
import numpy.typing as npt

from gridmap_cli.evaluation.relation_nees import (
    CHI2_3_MEDIAN,
    adjoint,
    between,
    log_map,
    relative_covariance,
)
from gridmap_cli.evaluation.relations import Relations, read_relations
from gridmap_cli.poses.correction.pose_graph import PoseGraph
from gridmap_cli.poses.correction.scan_match import FALLBACK
from gridmap_cli.poses.correction.slam import SlamParams, SlamResult, slam_log
from gridmap_cli.poses.sync import interpolate_pose
from gridmap_cli.poses.uncertainty.pose_belief import calibrated_graph
from gridmap_cli.readers import read_logs
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.records import PoseTrack
from gridmap_cli.robot import robot_from_log

sys.path.insert(0, str(Path(__file__).resolve().parent))
from slam_relations import DATA, LOGS

F64 = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Nees:
    """NEES of every relation scored, with the share of the predicted translational variance
    the graph gives (the rest is the odometry's over the stretch to the relation's stamp)."""

    values: F64
    graph_share: F64
    at_scans: npt.NDArray[np.bool_]  # both ends within 5 ms of a kept scan

    def row(self) -> str:
        v, exact = self.values, self.values[self.at_scans]
        ends = f"{np.median(exact):.2f} ({len(exact)})" if len(exact) else "- (0)"
        return (
            f"{len(v)} | {np.median(v):.2f} | {v.mean():.2f} | {ends} | "
            f"{np.median(self.graph_share):.2f}"
        )


def _pose(track: PoseTrack, k: int) -> F64:
    return np.array([track.x_m[k], track.y_m[k], track.theta_rad[k]])


def odometry_noise(result: SlamResult, odometry: PoseTrack) -> tuple[float, float]:
    """Variance per metre of motion (m^2, rad^2) of the odometry's steps between consecutive
    matched scans against the scan matcher's: median-based, as a random walk (module text)."""
    sm = result.scan_matched.track
    ox, oy, oth, _ = interpolate_pose(odometry, sm.stamp_ns)
    odo = np.column_stack([ox, oy, oth])
    rows = []
    for k in range(1, len(sm)):
        if result.scan_matched.status[k] == FALLBACK:
            continue
        ref = between(_pose(sm, k - 1), _pose(sm, k))
        e = log_map(between(ref, between(odo[k - 1], odo[k])))
        motion = math.hypot(ref[0], ref[1]) + abs(ref[2])
        if motion > 0.05:
            rows.append((e[0] ** 2 + e[1] ** 2, e[2] ** 2, motion))
    a = np.array(rows)
    return float(np.median(a[:, 0] / a[:, 2]) / 1.386), float(np.median(a[:, 1] / a[:, 2]) / 0.455)


def score(
    result: SlamResult,
    graph: PoseGraph,
    odometry: PoseTrack,
    relations: Relations,
    offset_s: float,
    scale: tuple[float, float],
) -> Nees:
    """NEES of each relation under ``graph`` (the module text); ``scale`` the factors its noise
    was scaled by, applied to the scan-to-keyframe offsets too."""
    p = SlamParams()
    poses, nodes = result.poses, result.keyframes
    values = gtsam.Values()
    for k, (x, y, th) in enumerate(poses):
        values.insert(k, gtsam.Pose2(float(x), float(y), float(th)))
    marginals = gtsam.Marginals(graph._factors(), values)
    scans, matched = result.track, result.scan_matched.track
    stamps = scans.stamp_ns
    q_xy, q_th = odometry_noise(result, odometry)

    def nearest(t: int) -> tuple[int, int]:
        k = int(np.clip(np.searchsorted(stamps, t), 1, len(stamps) - 1))
        k = k if abs(stamps[k] - t) < abs(t - stamps[k - 1]) else k - 1
        return k, abs(int(stamps[k]) - t)

    def attach(s: int) -> tuple[int, F64, F64]:
        """Keyframe index, the scan's offset from it and that offset's covariance."""
        a = int(np.searchsorted(nodes, s, side="right") - 1)
        if a + 1 < len(nodes) and stamps[nodes[a + 1]] - stamps[s] < stamps[s] - stamps[nodes[a]]:
            a += 1
        offset = between(_pose(matched, int(nodes[a])), _pose(matched, s))
        if int(nodes[a]) == s:
            return a, offset, np.zeros((3, 3))
        d = math.hypot(offset[0], offset[1])
        sxy = scale[0] * (p.sigma_xy_m + p.sigma_xy_per_m * d)
        sth = scale[1] * (p.sigma_theta_rad + p.sigma_theta_per_m * d)
        return a, offset, np.diag([sxy**2, sxy**2, sth**2])

    def stretch(s: int, t: int) -> tuple[F64, F64]:
        """The odometry's motion from scan ``s`` to stamp ``t`` and its covariance."""
        ax, ay, ath, _ = interpolate_pose(odometry, np.array([stamps[s]]))
        bx, by, bth, _ = interpolate_pose(odometry, np.array([t]))
        g = between(np.array([ax[0], ay[0], ath[0]]), np.array([bx[0], by[0], bth[0]]))
        m = math.hypot(g[0], g[1]) + abs(g[2])
        return g, np.diag([q_xy * m, q_xy * m, q_th * m])

    out, share, exact = [], [], []
    shift = round(offset_s * 1e9)
    for t1, t2, dx, dy, dth in zip(
        relations.t1_ns - shift, relations.t2_ns - shift,
        relations.dx_m, relations.dy_m, relations.dtheta_rad, strict=True,
    ):  # fmt: skip
        (s1, g1), (s2, g2) = nearest(int(t1)), nearest(int(t2))
        a, la, na = attach(s1)
        b, lb, nb = attach(s2)
        pa, pb = _pose(scans, s1), _pose(scans, s2)
        if s1 == s2:
            cov = np.zeros((3, 3))
        else:
            if a == b:
                c = marginals.marginalCovariance(a)
                joint = np.block([[c, c], [c, c]])
            else:
                jm = marginals.jointMarginalCovariance(gtsam.KeyVector([a, b]))
                joint = np.block([[jm.at(a, a), jm.at(a, b)], [jm.at(b, a), jm.at(b, b)]])
            # the keyframes' perturbations carried to the scans, plus the offsets' own noise
            ja = adjoint(between(la, np.zeros(3)))
            jb = adjoint(between(lb, np.zeros(3)))
            lift = np.block([[ja, np.zeros((3, 3))], [np.zeros((3, 3)), jb]])
            scan_joint = lift @ joint @ lift.T
            scan_joint[:3, :3] += na
            scan_joint[3:, 3:] += nb
            cov = relative_covariance(pa, pb, scan_joint)
        m1, c1 = stretch(s1, int(t1))
        m2, c2 = stretch(s2, int(t2))
        ea = np.array(_compose(pa, m1))
        eb = np.array(_compose(pb, m2))
        estimate = between(ea, eb)
        carry = adjoint(between(m2, np.zeros(3)))
        left = adjoint(between(estimate, np.zeros(3)))
        graph_part = carry @ cov @ carry.T
        total = graph_part + left @ c1 @ left.T + c2
        if np.linalg.det(total) < 1e-18:
            continue
        e = log_map(between(np.array([dx, dy, dth]), estimate))
        out.append(float(e @ np.linalg.solve(total, e)))
        share.append(float(np.trace(graph_part[:2, :2]) / np.trace(total[:2, :2])))
        exact.append(max(g1, g2) <= 5_000_000)
    return Nees(np.array(out), np.array(share), np.array(exact, dtype=bool))


def _compose(a: F64, b: F64) -> tuple[float, float, float]:
    c, s = math.cos(a[2]), math.sin(a[2])
    return a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", nargs="+", choices=sorted(LOGS), default=list(LOGS))
    args = parser.parse_args(argv)
    if not (DATA / "carmen").is_dir():
        print(f"no shared data at {DATA}", file=sys.stderr)
        return 1
    print(f"NEES of the benchmark's relations (consistent: median {CHI2_3_MEDIAN:.2f}, mean 3)")
    print()
    print(
        "| log | noise | scale (xy, theta) | relations | median | mean | median at kept scans "
        "(n) | graph's share of the variance |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name in args.logs:
        log_file, relations_file, offset = LOGS[name]
        path = DATA / "carmen" / log_file
        data = read_logs((path,), None, ReadOptions())
        relations = read_relations(DATA / "slam-benchmark" / relations_file)
        result = slam_log(data, robot_from_log(path, data.metadata))
        assert result.graph is not None
        fitted, scale = calibrated_graph(result.graph, result.poses)
        for label, graph, factors in (
            ("hand-set", result.graph, (1.0, 1.0)),
            ("calibrated", fitted, scale),
        ):
            nees = score(result, graph, data.poses, relations, offset, factors)
            print(
                f"| {name} | {label} | {factors[0]:.2f}, {factors[1]:.2f} | {nees.row()} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
