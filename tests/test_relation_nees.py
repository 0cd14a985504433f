"""NEES of relative poses (gridmap_cli.evaluation.relation_nees.py): the covariance carried onto a
relative pose, and the normalised error a consistent estimate gives."""

from __future__ import annotations

import math

import gtsam
import numpy as np

from gridmap_cli.evaluation.relation_nees import (
    CHI2_3_MEDIAN,
    adjoint,
    between,
    log_map,
    nees,
    relative_covariance,
)


def _exp(v: np.ndarray) -> np.ndarray:
    x, y, th = v
    if abs(th) < 1e-12:
        return np.array([x, y, th])
    s, c = math.sin(th) / th, (1 - math.cos(th)) / th
    return np.array([s * x - c * y, c * x + s * y, th])


def _right(pose: np.ndarray, d: np.ndarray) -> np.ndarray:
    step = _exp(d)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.array([pose[0] + c * step[0] - s * step[1], pose[1] + s * step[0] + c * step[1],
                     pose[2] + step[2]])  # fmt: skip


def test_the_lie_pieces_agree_with_gtsam() -> None:
    pose = np.array([1.5, -0.7, 2.2])
    assert np.allclose(adjoint(pose), gtsam.Pose2(*pose).AdjointMap())
    assert np.allclose(log_map(pose), gtsam.Pose2.Logmap(gtsam.Pose2(*pose)))
    a, b = np.array([0.3, 0.1, 0.4]), np.array([2.0, 1.0, -0.5])
    rel = gtsam.Pose2(*a).between(gtsam.Pose2(*b))
    assert np.allclose(between(a, b), [rel.x(), rel.y(), rel.theta()])


def test_a_consistent_joint_covariance_gives_the_chi_square_nees() -> None:
    rng = np.random.default_rng(3)
    a, b = np.array([0.0, 0.0, 0.3]), np.array([4.0, 2.0, 1.2])
    root = rng.normal(0.0, 0.02, (6, 6))
    joint = root @ root.T + np.diag([1e-4, 1e-4, 1e-5] * 2)
    truth = between(a, b)
    cov = relative_covariance(a, b, joint)
    draws = rng.multivariate_normal(np.zeros(6), joint, 4000)
    values = np.array(
        [nees(between(_right(a, d[:3]), _right(b, d[3:])), truth, cov) for d in draws]
    )
    assert abs(values.mean() - 3.0) < 0.2 and abs(np.median(values) - CHI2_3_MEDIAN) < 0.2
    # the same errors against a covariance four times too wide: a quarter of the NEES
    assert abs(np.mean([nees(between(_right(a, d[:3]), _right(b, d[3:])), truth, 4 * cov)
                        for d in draws[:1000]]) - 0.75) < 0.1  # fmt: skip


def test_correlated_ends_cancel_in_the_relative_pose() -> None:
    a, b = np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])
    shared = np.diag([0.01, 0.01, 0.0])  # both poses shifted together, no turn
    joint = np.block([[shared, shared], [shared, shared]])
    assert np.allclose(relative_covariance(a, b, joint), 0.0, atol=1e-15)
