"""ROS frames and transforms, reduced to what a planar map needs.

Frame ids are compared without a leading ``/`` (ROS 1 recordings have both spellings). A static
transform tree maps each child frame to its parent and the 3-D transform between them; the
mounting pose of a sensor is the chain from the robot's base frame to the sensor frame,
composed in 3-D and then projected onto the base frame's plane (position x, y and the direction
of the sensor's x axis).
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import wrap_angle

#: (x, y, z, w) unit quaternion
Quaternion = tuple[float, float, float, float]
Vector = tuple[float, float, float]

#: The rotation that turns nothing.
IDENTITY_ROTATION: Quaternion = (0.0, 0.0, 0.0, 1.0)


def frame_name(frame_id: str) -> str:
    """A frame id as gridmap compares it: without leading slashes."""
    return frame_id.lstrip("/")


#: A quaternion shorter than this is no rotation (a zeroed message field), not a tiny one.
MIN_QUATERNION_NORM = 1e-6


def rotation_problem(q: Quaternion) -> str | None:
    """What makes ``q`` no rotation (not finite, or zero norm: ROS zero-fills an unset
    orientation), or None; taken as identity it would map nonsense without a word."""
    norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]
    text = f"quaternion ({', '.join(f'{float(v):g}' for v in q)})"
    if not math.isfinite(norm2):
        return f"{text} is not finite"
    if norm2 < MIN_QUATERNION_NORM * MIN_QUATERNION_NORM:
        return f"{text} has zero norm: not a rotation"
    return None


def bad_rotations(q: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
    """:func:`rotation_problem` is not None, for (N, 4) quaternions at once."""
    with np.errstate(over="ignore", invalid="ignore"):
        norm2 = np.sum(q * q, axis=1)
    return np.asarray(~np.isfinite(norm2) | (norm2 < MIN_QUATERNION_NORM**2), dtype=np.bool_)


def yaw_of(q: Quaternion) -> float:
    """Heading (rad, wrapped) of the x axis of a frame rotated by quaternion ``q``.

    A rotation about z alone (the planar case) gives exactly ``2 * atan2(qz, qw)``; otherwise the
    rotated x axis is projected onto the plane.
    """
    x, y, z, w = q
    if x == 0.0 and y == 0.0:
        yaw = 2.0 * math.atan2(z, w)
    else:
        # the rotated x axis is (1 - 2(y^2 + z^2), 2(xy + wz), 2(xz - wy)): its heading
        yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    # wrap_angle's arithmetic on a Python float (the same fmod-based % as numpy's, so the same
    # bits), about 20 times faster than a numpy call per message
    return (yaw + math.pi) % (2.0 * math.pi) - math.pi


def yaws_of(
    qx: npt.NDArray[np.float64],
    qy: npt.NDArray[np.float64],
    qz: npt.NDArray[np.float64],
    qw: npt.NDArray[np.float64],
) -> npt.NDArray[np.float64]:
    """:func:`yaw_of` of each row, to the bit: each atan2 in Python's ``math`` (numpy's arctan2
    may take SIMD code paths that round otherwise), the wrap in numpy (the same fmod-based
    remainder as the scalar's), with no Python call a row."""
    x, y, z, w = (np.asarray(v, dtype=np.float64) for v in (qx, qy, qz, qw))
    atan2 = math.atan2
    if not (x.any() or y.any()):  # all planar: 2 atan2(qz, qw)
        raw = 2.0 * np.asarray([atan2(b, a) for b, a in zip(z.tolist(), w.tolist(), strict=True)])
    else:
        raw = np.asarray([
            2.0 * atan2(c, d) if a == 0.0 and b == 0.0
            else atan2(2.0 * (d * c + a * b), 1.0 - 2.0 * (b * b + c * c))
            for a, b, c, d in zip(x.tolist(), y.tolist(), z.tolist(), w.tolist(), strict=True)
        ])  # fmt: skip
    return wrap_angle(raw.reshape(len(z)))


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

    def up(self) -> float:
        """The z component, in the parent frame, of the child frame's z axis: 1 for a child
        level and upright, -1 for one turned upside down, whose x-y plane is the parent's
        mirrored (a direction ``a`` to the child's left lies ``a`` to the parent's right)."""
        x, y, z, w = self.rotation
        # R33 of the rotation, the quaternion's norm divided out (recorded ones are not all unit)
        return (w * w + z * z - x * x - y * y) / (x * x + y * y + z * z + w * w)


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


def _qmul_arrays(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """:func:`_qmul` on (N, 4) arrays of (x, y, z, w)."""
    ax, ay, az, aw = a.T
    bx, by, bz, bw = b.T
    return np.stack(
        (
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ),
        axis=1,
    )


def _rotate_arrays(
    q: npt.NDArray[np.float64], v: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """:func:`_rotate` on (N, 4) quaternions and (N, 3) vectors."""
    x, y, z, w = q.T
    vx, vy, vz = v.T
    cx, cy, cz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
    ddx, ddy, ddz = y * cz - z * cy, z * cx - x * cz, x * cy - y * cx
    return np.stack(
        (vx + 2.0 * (w * cx + ddx), vy + 2.0 * (w * cy + ddy), vz + 2.0 * (w * cz + ddz)), axis=1
    )


def _yaws(q: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """:func:`yaw_of` of (N, 4) quaternions at once (a pose track's worth)."""
    x, y, z, w = q.T
    planar = (x == 0.0) & (y == 0.0)
    tilted = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.asarray(wrap_angle(np.where(planar, 2.0 * np.arctan2(z, w), tilted)))


@dataclass
class TransformSeries:
    """The transforms of one parent -> child pair on ``/tf``, as they arrive (any order)."""

    stamps: list[int] = field(default_factory=list)
    values: list[tuple[float, ...]] = field(default_factory=list)  # tx, ty, tz, qx, qy, qz, qw

    def add(self, stamp_ns: int, transform: Transform) -> None:
        self.stamps.append(stamp_ns)
        self.values.append((*transform.translation, *transform.rotation))

    def changes(self) -> bool:
        """True if the transform ever differs from its first value: a moving joint."""
        first = self.values[0]
        return any(v != first for v in self.values)

    def first(self) -> Transform:
        v = self.values[0]
        return Transform((v[0], v[1], v[2]), (v[3], v[4], v[5], v[6]))

    def arrays(self) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
        """Stamps (N,), sorted and unique (a repeated stamp: the first transform wins), and the
        transforms at them, (N, 7)."""
        stamps = np.asarray(self.stamps, dtype=np.int64)
        order = np.argsort(stamps, kind="stable")
        stamps = stamps[order]
        keep = np.ones(len(stamps), dtype=bool)
        keep[1:] = stamps[1:] != stamps[:-1]
        values = np.asarray(self.values, dtype=np.float64).reshape(-1, 7)[order[keep]]
        return stamps[keep], values

    def at(self, stamp_ns: npt.NDArray[np.int64]) -> npt.NDArray[np.float64]:
        """Transforms (N, 7) at the given stamps, interpolated (translation linearly, rotation
        along the shorter arc, normalised); NaN outside the series' time span. A stamp of the
        series gives its transform exactly."""
        stamps, values = self.arrays()
        out = np.full((len(stamp_ns), 7), np.nan)
        inside = (stamp_ns >= stamps[0]) & (stamp_ns <= stamps[-1])
        t = stamp_ns[inside]
        hi = np.clip(np.searchsorted(stamps, t, side="left"), 0, len(stamps) - 1)
        exact = stamps[hi] == t
        lo = np.maximum(hi - 1, 0)
        span = (stamps[hi] - stamps[lo]).astype(np.float64)
        w = np.where(exact | (span == 0), 0.0, (t - stamps[lo]) / np.where(span == 0, 1.0, span))
        a = np.where(exact[:, None], values[hi], values[lo])
        b = values[hi]
        trans = a[:, :3] + w[:, None] * (b[:, :3] - a[:, :3])
        qb = np.where((np.sum(a[:, 3:] * b[:, 3:], axis=1) < 0.0)[:, None], -b[:, 3:], b[:, 3:])
        q = (1.0 - w)[:, None] * a[:, 3:] + w[:, None] * qb
        q /= np.linalg.norm(q, axis=1)[:, None]
        q = np.where((w == 0.0)[:, None], a[:, 3:], q)
        out[inside] = np.concatenate((trans, q), axis=1)
        return out


#: One link of a chain: parent, child, and a fixed transform or a series over time.
Link = tuple[str, str, "Transform | TransformSeries"]


class TransformBuffer:
    """Every transform of a recording: fixed ones (``/tf_static``, and ``/tf`` pairs that never
    change) and moving ones (``/tf`` pairs that change), child frame -> parent.

    :attr:`fixed` is the tree sensor mountings come from: a transform that changes over time is
    never a mounting. Chains through moving links (odom -> base_footprint -> base_link, or
    map -> odom -> base) are composed over time by :meth:`track`.
    """

    def __init__(self, fixed: FrameTree, series: dict[tuple[str, str], TransformSeries]) -> None:
        self.fixed = fixed
        self.series = series
        self.moving = {pair for pair, s in series.items() if s.changes()}
        # chains over time use a pair's series where /tf has one (a still robot's odometry
        # never changes, yet it is odometry), the fixed tree elsewhere
        self.links: dict[str, tuple[str, Transform | TransformSeries]] = {
            child: (parent, s) for (parent, child), s in series.items()
        }
        for child, (parent, transform) in fixed.parent.items():
            self.links.setdefault(child, (parent, transform))

    def moves(self, top: str, bottom: str) -> bool:
        """True if the chain from ``top`` down to ``bottom`` has a transform that changes."""
        links = self.chain(top, bottom) or []
        return any((parent, child) in self.moving for parent, child, _ in links)

    def chain(self, top: str, bottom: str) -> list[Link] | None:
        """The links from ``top`` down to ``bottom``, or None when ``bottom`` is not below."""
        top, bottom = frame_name(top), frame_name(bottom)
        links: list[Link] = []
        current = bottom
        for _ in range(len(self.links) + 1):
            if current == top:
                return links[::-1]
            link = self.links.get(current)
            if link is None:
                return None
            parent, transform = link
            links.append((parent, current, transform))
            current = parent
        return None  # a cycle

    def lowest_moving_child(self, top: str, sensors: Collection[str] = ()) -> str | None:
        """Follow the moving transforms down from ``top`` while each frame has one moving child
        that is not a sensor frame: the robot's base as TF odometry gives it (odom ->
        base_footprint, not its fixed children; map -> odom -> base_link, not a panning laser).
        None when ``top`` has no moving child."""
        moving = list(self.moving) or list(self.series)
        current, seen = frame_name(top), set()
        while current not in seen:
            seen.add(current)
            children = [c for p, c in moving if p == current]
            if len(children) != 1 or children[0] in sensors:
                break
            current = children[0]
        return None if current == frame_name(top) else current

    def track(
        self, top: str, bottom: str
    ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]] | None:
        """The planar pose of ``bottom`` in ``top`` over time: stamps (N,) and (x, y, yaw) (N, 3).

        Stamps are those of the series with the most stamps (the odometry's; the lowest of equals);
        the other series are interpolated at them, and stamps outside any of their spans are
        dropped. None when there is no chain, or no series in it.
        """
        links = self.chain(top, bottom)
        if links is None:
            return None
        series = [(p, c, t) for p, c, t in links if isinstance(t, TransformSeries)]
        if not series:
            return None
        # the densest series sets the rate (odom -> base, not a localiser's map -> odom)
        densest = max(reversed(series), key=lambda link: len(set(link[2].stamps)))[2]
        stamps, _ = densest.arrays()
        n = len(stamps)
        trans = np.zeros((n, 3))
        rot = np.tile(np.array(IDENTITY_ROTATION), (n, 1))
        for _, _, link in links:
            if isinstance(link, TransformSeries):
                values = link.at(stamps)
                t, q = values[:, :3], values[:, 3:]
            else:
                t = np.tile(np.array(link.translation), (n, 1))
                q = np.tile(np.array(link.rotation), (n, 1))
            trans = trans + _rotate_arrays(rot, t)
            rot = _qmul_arrays(rot, q)
        ok = ~np.isnan(trans).any(axis=1) & ~np.isnan(rot).any(axis=1)
        planar = np.column_stack((trans[ok, 0], trans[ok, 1], _yaws(rot[ok])))
        return stamps[ok], planar.reshape(-1, 3)
