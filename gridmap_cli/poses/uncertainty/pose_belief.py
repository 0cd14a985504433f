"""The pose graph's belief about a track (``--pose slam``): each keyframe's covariance in the map
frame, and joint draws of the whole track.

The odometry-error model (:mod:`.pose_uncertainty`) carries a covariance that only grows along the
path. A pose graph with loop closures knows better: where a loop closed, the poses on it are
pinned to each other, and their covariance shrinks; where the robot went once, it grows as the
odometry's does.

Two covariances are kept, because the graph's marginals answer a question a map does not ask:

- :attr:`PoseBelief.cov`, the graph's **marginals** (gtsam's, turned into the map frame): each
  keyframe's uncertainty relative to the first pose, which the graph holds fixed. ``gridmap
  trajectory --pose slam`` writes these.
- :attr:`PoseBelief.shape_cov`, the marginals **with the common rigid motion taken out**: a
  whole map turned by a degree about its first pose is the same map, yet that turn moves a wall
  30 m away by half a metre and the first-pose marginals count it (on a real lab log the
  median position spread falls about five-fold once the rigid motion is out). The rigid motion
  is the least squares fit of the keyframe positions' error (a shift and a turn about their
  centroid); taking it out is linear to first order, so ``shape_cov`` is exact for the
  linearised graph (:func:`shape_covariance`). Error-aware mapping uses these: crisp where
  loops closed, grey where the robot went once, not grey merely for being far from the start.

The graph's edge noise is set by hand (:class:`~gridmap_cli.poses.correction.slam.SlamParams`), the
same for every log. For a map it is **calibrated on the graph's own residuals**
(:func:`calibrated_graph`): where loops closed, the graph sees the same places from several
passes, and how far the closures and the chain disagree at the optimum says how large the noise
between passes really is (the a posteriori variance factor of a least-squares adjustment, one
for translation and one for rotation: the whitened squared residuals over their redundancy,
:meth:`~gridmap_cli.poses.correction.pose_graph.PoseGraph.residual_budget`). On the shared CARMEN
logs the factors are 0.28-0.46 for translation and 0.20-0.34 for rotation: the hand-set noise is 2-5
times wider than the passes' disagreement, and its draws doubled walls that the optimum's map
draws once. Without enough redundancy (no loop, or a few closures) the hand-set noise is kept.
``gridmap trajectory`` writes the hand-set marginals instead (``calibrate=False``): against the
SLAM benchmark's relations, which also carry errors the passes share, those are the consistent
ones (docs/scan-matching.md, "Uncertainty").

The draws (:meth:`PoseBelief.tracks`, for the sampled expected map) are joint, not per pose: the
graph is linearised at its optimum and sampled as one Gaussian over all keyframes
(:meth:`~gridmap_cli.poses.correction.pose_graph.PoseGraph.sample`), so neighbouring keyframes move
together as the edges between them say, and each draw is then laid on the optimum by the rigid
motion that fits it best (as :attr:`~PoseBelief.shape_cov` is). Independent draws from each pose's
marginal would shake every keyframe against its neighbours and smear walls that every draw of
the joint belief keeps straight.

Numpy only: gtsam is used through the :class:`~gridmap_cli.poses.correction.pose_graph.PoseGraph` a
:class:`~gridmap_cli.poses.correction.slam.SlamResult` carries, when :func:`slam_belief` is called.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import compose, inverse, wrap_angle
from gridmap_cli.poses.sync import interpolate_pose
from gridmap_cli.poses.uncertainty.pose_uncertainty import PoseUncertainty
from gridmap_cli.records import PoseTrack

if TYPE_CHECKING:
    from gridmap_cli.poses.correction.pose_graph import PoseGraph
    from gridmap_cli.poses.correction.slam import SlamResult

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]

#: Redundancy (independent checks of the noise, :meth:`PoseGraph.residual_budget`) below which a
#: variance factor is not estimated: a few closures say too little about the scale.
MIN_REDUNDANCY = 20.0
#: Rounds of the variance factors: scaling translation and rotation apart shifts the edges'
#: redundancy a little, so the factors are estimated again on the scaled graph (on the shared
#: logs the second round moves them by under 10 %, the third by under 3 %).
CALIBRATION_ROUNDS = 3


def calibrated_graph(graph: PoseGraph, poses: F64) -> tuple[PoseGraph, tuple[float, float]]:
    """``graph`` with every edge's standard deviations scaled by the a posteriori factors of
    translation and rotation at ``poses`` (the optimum), and the factors (the module text).
    A component with less than :data:`MIN_REDUNDANCY` keeps the hand-set noise (factor 1).

    The optimum is kept: the factors change the marginals, not the track (the optimiser's
    weighting of translation against rotation moves by the ratio of the two factors, which the
    first-order marginals at the same poses do not see)."""
    factors = np.ones(2)
    scaled = graph
    for _ in range(CALIBRATION_ROUNDS):
        budget = scaled.residual_budget(poses)
        step = np.ones(2)
        enough = budget[:, 1] >= MIN_REDUNDANCY
        step[enough] = np.sqrt(np.maximum(budget[enough, 0], 1e-12) / budget[enough, 1])
        factors = factors * step
        scaled = _scaled(graph, float(factors[0]), float(factors[1]))
        if np.all(np.abs(step - 1.0) < 0.02):
            break
    return scaled, (float(factors[0]), float(factors[1]))


def _scaled(graph: PoseGraph, xy: float, theta: float) -> PoseGraph:
    edges = [
        dataclasses.replace(
            e,
            sigma_xy_m=e.sigma_xy_m * xy,
            sigma_theta_rad=e.sigma_theta_rad * theta,
            weak_sigma_m=e.weak_sigma_m * xy,
        )
        for e in graph.edges
    ]
    return dataclasses.replace(graph, edges=edges)


def frame_rotations(theta_rad: F64) -> F64:
    """Per pose, shape (K, 3, 3): the map-frame image of a step in the pose's own frame
    (position rotated by the heading, heading unchanged), to first order."""
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    j = np.zeros((len(theta_rad), 3, 3))
    j[:, 0, 0], j[:, 0, 1], j[:, 1, 0], j[:, 1, 1] = c, -s, s, c
    j[:, 2, 2] = 1.0
    return j


def _symmetric(cov: F64) -> F64:
    return 0.5 * (cov + np.transpose(cov, (0, 2, 1)))


def to_map_frame(cov: F64, theta_rad: F64) -> F64:
    """Covariances (K, 3, 3) of (x, y, theta) in each pose's own frame, as gtsam gives a Pose2's
    marginal, turned into the map frame: the position block rotated by the pose's heading."""
    j = frame_rotations(theta_rad)
    return _symmetric(j @ cov @ np.transpose(j, (0, 2, 1)))


def rigid_fit(poses: F64) -> tuple[F64, F64]:
    """The least-squares rigid motion of a small map-frame error ``e`` (K, 3) of the keyframe
    positions, ``a = sum_k B_k e_k`` (shift x, shift y, turn about the centroid), and what it
    does to each pose, ``G_k a``: ``B`` (K, 3, 3) and ``G`` (K, 3, 3). Fewer than two distinct
    positions fit a shift alone."""
    k = len(poses)
    q = poses[:, :2] - poses[:, :2].mean(axis=0)
    spread = float((q * q).sum())
    b = np.zeros((k, 3, 3))
    b[:, 0, 0] = b[:, 1, 1] = 1.0 / k
    if spread > 1e-12:
        b[:, 2, 0], b[:, 2, 1] = -q[:, 1] / spread, q[:, 0] / spread
    g = np.zeros((k, 3, 3))
    g[:, 0, 0] = g[:, 1, 1] = g[:, 2, 2] = 1.0
    g[:, 0, 2], g[:, 1, 2] = -q[:, 1], q[:, 0]
    return b, g


def shape_covariance(poses: F64, cov: F64, product: Callable[[F64], F64]) -> F64:
    """Map-frame covariances (K, 3, 3) of the keyframes once the common rigid motion is taken
    out (the module text): ``(I - G B) Sigma (I - G B)^T``, block by block.

    ``cov`` (K, 3, 3): the map-frame marginals; ``product(V)`` for ``V`` (M, K, 3) gives
    ``Sigma V`` in the map frame (the joint covariance is never formed)."""
    b, g = rigid_fit(poses)
    c = product(np.transpose(b, (1, 0, 2)))  # (3, K, 3): row i of B Sigma, per keyframe
    ck = np.transpose(c, (1, 0, 2))  # (K, 3, 3): (B Sigma)[:, block k]
    bsb = np.einsum("ikj,kmj->im", c, b)  # B Sigma B^T, (3, 3)
    gc = g @ ck
    out = cov - gc - np.transpose(gc, (0, 2, 1)) + g @ bsb @ np.transpose(g, (0, 2, 1))
    return _symmetric(out)


def align_draws(draws: F64, poses: F64) -> F64:
    """Each draw (S, K, 3) laid on ``poses`` (K, 3) by the rigid motion that best fits its
    keyframe positions to them (least squares, the planar Procrustes fit)."""
    out = np.empty_like(draws)
    centre = poses[:, :2].mean(axis=0)
    b = poses[:, :2] - centre
    for s, draw in enumerate(draws):
        mid = draw[:, :2].mean(axis=0)
        a = draw[:, :2] - mid
        h = a.T @ b
        turn = float(np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1]))
        c, sn = np.cos(turn), np.sin(turn)
        out[s, :, 0] = centre[0] + c * a[:, 0] - sn * a[:, 1]
        out[s, :, 1] = centre[1] + sn * a[:, 0] + c * a[:, 1]
        out[s, :, 2] = wrap_angle(draw[:, 2] + turn)
    return out


@dataclass(frozen=True)
class PoseBelief:
    """What a pose graph believes about its keyframes (the module text).

    ``stamp_ns`` (K,): the keyframes' stamps; ``poses`` (K, 3): their optimised x, y (metres)
    and theta (radians) in the map frame; ``cov`` (K, 3, 3): their marginal covariance of
    (x, y, theta) in the map frame (m^2, m rad, rad^2), relative to the first pose;
    ``shape_cov`` (K, 3, 3): the same with the common rigid motion taken out; ``draws``
    (S, K, 3): joint draws of the keyframe poses, each laid on ``poses`` by its best rigid fit
    (S may be 0); ``scale`` the factors the hand-set edge noise was calibrated by
    (translation, rotation; :func:`calibrated_graph`).
    """

    stamp_ns: I64
    poses: F64
    cov: F64
    shape_cov: F64
    draws: F64
    scale: tuple[float, float] = (1.0, 1.0)

    @property
    def uncertainty(self) -> PoseUncertainty:
        """The shape covariance at the keyframes, in the form the error-aware model takes
        (linear in time between keyframes)."""
        return PoseUncertainty(self.stamp_ns, self.poses[:, 0], self.poses[:, 1], self.shape_cov)

    def marginals_at(self, stamp_ns: I64) -> F64:
        """The marginals at ``stamp_ns`` (M,): shape (M, 3, 3), linear in time between keyframes
        (a mix of two positive-definite matrices, so positive-definite), the nearest
        keyframe's outside them."""
        return PoseUncertainty(self.stamp_ns, self.poses[:, 0], self.poses[:, 1], self.cov).at(
            stamp_ns
        )

    def tracks(self, track: PoseTrack, count: int) -> list[PoseTrack]:
        """``count`` draws of ``track`` (the optimised track at any stamps): each keyframe moves
        to its draw, every other pose with the keyframes around it (the correction
        ``draw (-) optimised`` interpolated in time, as :func:`.repair.carried` places the scans
        between keyframes). Raises ValueError when fewer than ``count`` draws are held."""
        if count > self.draws.shape[0]:
            raise ValueError(f"{count} tracks asked of a belief holding {self.draws.shape[0]}")
        ix, iy, ith = inverse(self.poses[:, 0], self.poses[:, 1], self.poses[:, 2])
        out = []
        for draw in self.draws[:count]:
            cx, cy, cth = compose(draw[:, 0], draw[:, 1], draw[:, 2], ix, iy, ith)
            correction = PoseTrack(stamp_ns=self.stamp_ns, x_m=cx, y_m=cy, theta_rad=cth)
            ax, ay, ath, _ = interpolate_pose(correction, track.stamp_ns)
            x, y, th = compose(ax, ay, ath, track.x_m, track.y_m, track.theta_rad)
            out.append(PoseTrack(stamp_ns=track.stamp_ns, x_m=x, y_m=y, theta_rad=th))
        return out


def slam_belief(
    result: SlamResult, samples: int = 0, seed: int = 0, calibrate: bool = True
) -> PoseBelief:
    """The belief of ``result``'s pose graph: marginals and shape covariances in the map frame
    and ``samples`` joint draws (seeded: the same seed, the same draws), of the graph whose
    noise is calibrated on its residuals (:func:`calibrated_graph`; ``calibrate=False``: the
    hand-set noise). Raises ValueError for a result that kept no graph."""
    graph = result.graph
    if graph is None:
        raise ValueError("the SLAM result kept no pose graph")
    poses = result.poses
    scale = (1.0, 1.0)
    if calibrate:
        graph, scale = calibrated_graph(graph, poses)
    # the hand-set graph's marginals, when the SLAM run already computed them
    kept = None if calibrate else result.covariance
    own = kept if kept is not None else graph.marginals(poses)
    cov = to_map_frame(own, poses[:, 2])
    j = frame_rotations(poses[:, 2])
    jt = np.transpose(j, (0, 2, 1))

    def product(vectors: F64) -> F64:  # map-frame Sigma V = J Sigma_own J^T V
        own_v = np.einsum("kij,mkj->mki", jt, vectors)
        out: F64 = np.einsum("kij,mkj->mki", j, graph.covariance_product(poses, own_v))
        return out

    draws = graph.sample(poses, samples, seed) if samples else np.zeros((0, *poses.shape))
    return PoseBelief(
        stamp_ns=result.scan_matched.track.stamp_ns[result.keyframes].astype(np.int64),
        poses=poses.copy(),
        cov=cov,
        shape_cov=shape_covariance(poses, cov, product),
        draws=align_draws(draws, poses),
        scale=scale,
    )
