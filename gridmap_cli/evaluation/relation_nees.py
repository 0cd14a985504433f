"""Whether a pose graph's covariances are honest: the normalised estimation error squared (NEES)
of relative poses against ground-truth relations.

For a relation between the poses ``a`` and ``b``, the estimate ``a^-1 b`` is off the true
relative pose by ``e = Log(truth^-1 a^-1 b)`` (x, y, theta in ``b``'s frame, the right
perturbation gtsam's Pose2 marginals are written in). If the graph's joint covariance of ``a``
and ``b`` is right, ``e^T C^-1 e`` follows a chi-square law with 3 degrees of freedom (mean 3,
median 2.37), ``C`` being that covariance carried onto the relative pose
(:func:`relative_covariance`). A median well under 2.37 says the covariances are too wide; over
it, too narrow. ``bench/slam_nees.py`` scores the shared CARMEN logs this way
(docs/scan-matching.md, "Uncertainty").

Numpy only; poses are (x, y, theta) rows in metres and radians.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import compose, inverse, wrap_angle

F64 = npt.NDArray[np.float64]

#: Median of the chi-square law with 3 degrees of freedom: a consistent NEES's median.
CHI2_3_MEDIAN = 2.366


def adjoint(pose: F64) -> F64:
    """The adjoint (3, 3) of a planar pose (x, y, theta): how a right perturbation of the frame
    ``pose`` maps into the frame it is expressed in, ``pose Exp(d) = Exp(Ad d) pose``."""
    x, y, th = (float(v) for v in pose)
    c, s = math.cos(th), math.sin(th)
    return np.array([[c, -s, y], [s, c, -x], [0.0, 0.0, 1.0]])


def between(a: F64, b: F64) -> F64:
    """``a^-1 b`` as a pose (3,)."""
    ix, iy, ith = inverse(a[0], a[1], a[2])
    x, y, th = compose(ix, iy, ith, b[0], b[1], b[2])
    return np.array([float(x), float(y), float(th)])


def log_map(pose: F64) -> F64:
    """The tangent vector (3,) of a planar pose: its exponential is the pose."""
    x, y, th = (float(v) for v in pose)
    th = float(wrap_angle(th))
    if abs(th) < 1e-9:
        return np.array([x, y, th])
    half = 0.5 * th
    k = half / math.tan(half)  # V^-1 = [[k, half], [-half, k]]
    return np.array([k * x + half * y, -half * x + k * y, th])


def relative_covariance(a: F64, b: F64, joint: F64) -> F64:
    """The covariance (3, 3) of ``a^-1 b`` (right perturbation, in ``b``'s frame) from the joint
    covariance (6, 6) of right perturbations of ``a`` and ``b`` (each in its own frame):
    ``d(a^-1 b) = -Ad((a^-1 b)^-1) d_a + d_b``."""
    rel = between(a, b)
    jac = np.hstack([-adjoint(between(rel, np.zeros(3))), np.eye(3)])
    out: F64 = jac @ joint @ jac.T
    return 0.5 * (out + out.T)


def nees(estimate: F64, truth: F64, cov: F64) -> float:
    """``e^T C^-1 e`` for an estimated relative pose against the true one (module text)."""
    e = log_map(between(truth, estimate))
    return float(e @ np.linalg.solve(cov, e))
