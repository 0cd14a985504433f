"""The pose graph's belief about a track (``--pose slam``): each keyframe's marginal covariance in
the map frame, and joint draws of the whole track.

The odometry-error model (:mod:`.pose_uncertainty`) carries a covariance that only grows along the
path. A pose graph with loop closures knows better: where a loop closed, the poses on it are
pinned to each other and to the start, and their covariance shrinks; where the robot went once,
it grows as the odometry's does. :class:`PoseBelief` holds that in the shapes the mapping stage
already takes: :attr:`PoseBelief.uncertainty` is a
:class:`~gridmap_cli.poses.pose_uncertainty.PoseUncertainty` (the analytic error-aware model
fades each reading by it) and :meth:`PoseBelief.tracks` gives whole tracks drawn from the graph
(the sampled expected map averages the maps of those).

The draws are joint, not per pose: the graph is linearised at its optimum and sampled as one
Gaussian over all keyframes (:meth:`~gridmap_cli.poses.pose_graph.PoseGraph.sample`), so
neighbouring keyframes move together as the edges between them say. Independent draws from each
pose's marginal would shake every keyframe against its neighbours and smear walls that every
draw of the joint belief keeps straight.

Numpy only: gtsam is used through the :class:`~gridmap_cli.poses.pose_graph.PoseGraph` a
:class:`~gridmap_cli.poses.slam.SlamResult` carries, when :func:`slam_belief` is called.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import compose, inverse
from gridmap_cli.poses.pose_uncertainty import PoseUncertainty
from gridmap_cli.poses.sync import interpolate_pose
from gridmap_cli.records import PoseTrack

if TYPE_CHECKING:
    from gridmap_cli.poses.slam import SlamResult

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]


def to_map_frame(cov: F64, theta_rad: F64) -> F64:
    """Covariances (K, 3, 3) of (x, y, theta) in each pose's own frame, as gtsam gives a Pose2's
    marginal, turned into the map frame: the position block rotated by the pose's heading."""
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    j = np.zeros((len(theta_rad), 3, 3))
    j[:, 0, 0], j[:, 0, 1], j[:, 1, 0], j[:, 1, 1] = c, -s, s, c
    j[:, 2, 2] = 1.0
    out = j @ cov @ np.transpose(j, (0, 2, 1))
    return 0.5 * (out + np.transpose(out, (0, 2, 1)))  # symmetric to the last bit


@dataclass(frozen=True)
class PoseBelief:
    """What a pose graph believes about its keyframes.

    ``stamp_ns`` (K,): the keyframes' stamps; ``poses`` (K, 3): their optimised x, y (metres)
    and theta (radians) in the map frame; ``cov`` (K, 3, 3): their marginal covariance of
    (x, y, theta) in the map frame (m^2, m rad, rad^2); ``draws`` (S, K, 3): joint draws of
    the keyframe poses (S may be 0).
    """

    stamp_ns: I64
    poses: F64
    cov: F64
    draws: F64

    @property
    def uncertainty(self) -> PoseUncertainty:
        """The covariance at the keyframes, in the shape the error-aware model takes (linear in
        time between keyframes)."""
        return PoseUncertainty(self.stamp_ns, self.poses[:, 0], self.poses[:, 1], self.cov)

    def at(self, stamp_ns: I64) -> F64:
        """Covariance at ``stamp_ns`` (M,): shape (M, 3, 3), linear in time between keyframes
        (a mix of positive-definite matrices, so positive-definite), the nearest keyframe's
        outside them."""
        return self.uncertainty.at(stamp_ns)

    def tracks(self, track: PoseTrack, count: int) -> list[PoseTrack]:
        """``count`` draws of ``track`` (the optimised track at any stamps): each keyframe moves
        to its draw, every other pose with the keyframes around it (the correction
        ``draw (-) optimised`` interpolated in time, as :func:`.slam.carried` places the scans
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


def slam_belief(result: SlamResult, samples: int = 0, seed: int = 0) -> PoseBelief:
    """The belief of ``result``'s pose graph: marginals in the map frame and ``samples`` joint
    draws (seeded: the same seed, the same draws). Raises ValueError for a result that kept no
    graph."""
    graph = result.graph
    if graph is None:
        raise ValueError("the SLAM result kept no pose graph")
    own = result.covariance if result.covariance is not None else graph.marginals(result.poses)
    draws = graph.sample(result.poses, samples, seed) if samples else np.zeros((0, *result.poses.shape))
    stamps = result.scan_matched.track.stamp_ns[result.keyframes].astype(np.int64)
    return PoseBelief(
        stamp_ns=stamps,
        poses=result.poses.copy(),
        cov=to_map_frame(own, result.poses[:, 2]),
        draws=draws,
    )
