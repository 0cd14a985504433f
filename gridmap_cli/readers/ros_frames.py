"""ROS frames and transforms, reduced to what a planar map needs.

Frame ids are compared without a leading ``/`` (ROS 1 recordings have both spellings). A static
transform tree maps each child frame to its parent and the 3-D transform between them; the
mounting pose of a sensor is the chain from the robot's base frame to the sensor frame,
composed in 3-D and then projected onto the base frame's plane (position x, y and the direction
of the sensor's x axis).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from gridmap_cli.geometry import wrap_angle

#: (x, y, z, w) unit quaternion
Quaternion = tuple[float, float, float, float]
Vector = tuple[float, float, float]

#: The rotation that turns nothing.
IDENTITY_ROTATION: Quaternion = (0.0, 0.0, 0.0, 1.0)


def frame_name(frame_id: str) -> str:
    """A frame id as gridmap compares it: without leading slashes."""
    return frame_id.lstrip("/")


def yaw_of(q: Quaternion) -> float:
    """Heading (rad, wrapped) of the x axis of a frame rotated by quaternion ``q``.

    A rotation about z alone (the planar case) gives exactly ``2 * atan2(qz, qw)``; otherwise the
    rotated x axis is projected onto the plane.
    """
    x, y, z, w = q
    if x == 0.0 and y == 0.0:
        return float(wrap_angle(2.0 * math.atan2(z, w)))
    # the rotated x axis is (1 - 2(y^2 + z^2), 2(xy + wz), 2(xz - wy)): its heading in the plane
    return float(wrap_angle(math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))))


def quaternion_of_yaw(theta_rad: float) -> Quaternion:
    """The rotation by ``theta_rad`` about z, (0, 0, sin(theta/2), cos(theta/2)): the inverse of
    :func:`yaw_of` up to wrapping (and about 1 ulp)."""
    half = 0.5 * float(theta_rad)
    return (0.0, 0.0, math.sin(half), math.cos(half))


def _qmul(a: Quaternion, b: Quaternion) -> Quaternion:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def _rotate(q: Quaternion, v: Vector) -> Vector:
    x, y, z, w = q
    vx, vy, vz = v
    # v' = v + 2w (q x v) + 2 q x (q x v)
    cx, cy, cz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
    ddx, ddy, ddz = y * cz - z * cy, z * cx - x * cz, x * cy - y * cx
    return (vx + 2.0 * (w * cx + ddx), vy + 2.0 * (w * cy + ddy), vz + 2.0 * (w * cz + ddz))


@dataclass(frozen=True)
class Transform:
    """A rigid transform: the child frame's origin and orientation in the parent frame."""

    translation: Vector
    rotation: Quaternion

    def then(self, child: Transform) -> Transform:
        """This transform followed by ``child`` (expressed in this transform's child frame)."""
        t = _rotate(self.rotation, child.translation)
        return Transform(
            (
                self.translation[0] + t[0],
                self.translation[1] + t[1],
                self.translation[2] + t[2],
            ),
            _qmul(self.rotation, child.rotation),
        )

    def planar(self) -> tuple[float, float, float]:
        """(x_m, y_m, yaw_rad) of the child frame in the parent frame's plane."""
        return self.translation[0], self.translation[1], yaw_of(self.rotation)


IDENTITY = Transform((0.0, 0.0, 0.0), IDENTITY_ROTATION)


class FrameTree:
    """Static transforms, child frame -> (parent frame, transform); the latest one wins."""

    def __init__(self) -> None:
        self.parent: dict[str, tuple[str, Transform]] = {}
        self.order: list[str] = []  # child frames in the order first seen

    def add(self, parent: str, child: str, transform: Transform) -> None:
        parent, child = frame_name(parent), frame_name(child)
        if child not in self.parent:
            self.order.append(child)
        self.parent[child] = (parent, transform)

    def __contains__(self, frame: str) -> bool:
        return frame_name(frame) in self.parent

    def lookup(self, base: str, frame: str) -> Transform | None:
        """Transform of ``frame`` in ``base`` (chained through intermediate frames), or None.

        None when ``frame`` is not below ``base`` in the tree.
        """
        base, frame = frame_name(base), frame_name(frame)
        chain: list[Transform] = []
        current = frame
        for _ in range(len(self.parent) + 1):
            if current == base:
                out = IDENTITY
                for step in reversed(chain):
                    out = out.then(step)
                return out
            link = self.parent.get(current)
            if link is None:
                return None
            current, transform = link
            chain.append(transform)
        return None  # a cycle: not a tree

    def root_of(self, frame: str) -> str:
        """The top of the chain above ``frame`` (for error messages)."""
        current = frame_name(frame)
        for _ in range(len(self.parent) + 1):
            link = self.parent.get(current)
            if link is None:
                return current
            current = link[0]
        return current
