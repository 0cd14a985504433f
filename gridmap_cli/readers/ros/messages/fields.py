"""Field values of ROS messages as gridmap stores them: header stamps as integer nanoseconds,
quaternions and transforms as :class:`~gridmap_cli.readers.ros.frames.Transform`, float32
fields as their decimals, ``sensor_msgs/Range`` values as reading / no echo / none."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.readers.ros.frames import Transform


def _stamp_ns(stamp: Any) -> int:
    """Integer nanoseconds of a ROS 1 / ROS 2 time or a JSON ``{"sec", "nsec"}`` object."""
    if isinstance(stamp, dict):
        return int(stamp["sec"]) * 1_000_000_000 + int(stamp["nsec"])
    if hasattr(stamp, "secs"):
        return int(stamp.secs) * 1_000_000_000 + int(stamp.nsecs)
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _quaternion(q: Any) -> tuple[float, float, float, float]:
    return float(q.x), float(q.y), float(q.z), float(q.w)


def _transform(t: Any) -> Transform:
    v = t.translation
    return Transform((float(v.x), float(v.y), float(v.z)), _quaternion(t.rotation))


def float32_decimal(values: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """float32 message fields as the shortest decimal (up to 9 places) each float32 stands for.

    ``sensor_msgs/Range`` and ``LaserScan`` carry float32: a range written as 1.234 arrives as
    1.2339999675750732. Reading it back as 1.234 keeps logs that went through ROS messages
    equal to the same run stored as CSV; both doubles round to the same float32.
    """
    v32 = np.atleast_1d(np.asarray(values, dtype=np.float32))
    exact = v32.astype(np.float64)
    out = exact.copy()
    todo = np.flatnonzero(np.isfinite(exact))
    for places in range(10):
        if len(todo) == 0:
            break
        candidate = np.round(exact[todo], places)
        ok = candidate.astype(np.float32) == v32[todo]
        out[todo[ok]] = candidate[ok]
        todo = todo[~ok]
    return out


def _f32(value: float) -> float:
    """One float32 field as its decimal, for error messages. Readings and sensor limits are
    converted together (:meth:`MessageAccumulator.finish`): converting each message's fields one by
    one through numpy took 2.6 s of a 3.6 s read of ``samples/corridor_loop_ros2.mcap``."""
    return float(float32_decimal(value)[0])


def _classify(value: float, max_range: float) -> float | None:
    """A sensor_msgs/Range value as gridmap stores it: None = no reading, inf = no echo.

    NaN is no reading, -inf "too close" (REP 117) and negative values are dropped; +inf and
    anything at or beyond ``max_range`` is no echo. Values below ``min_range`` are kept: the sync
    stage drops and counts them.
    """
    if math.isnan(value) or value < 0.0:
        return None
    if value >= max_range:
        return math.inf
    return value


def scan_limits_problem(frame: str, range_min: float, range_max: float) -> str | None:
    """Why a LaserScan's range limits cannot be used, or None: ``range_max`` is the range a
    beam with no echo reads and the sensor's reach on the map, so it must be a finite number
    above ``range_min`` (a NaN or infinite one would leave no echo and no bound)."""
    if 0.0 <= range_min < range_max and math.isfinite(range_max):
        return None
    return (
        f"laser '{frame}': need 0 <= range_min < range_max, range_max finite, got "
        f"{_f32(range_min)} and {_f32(range_max)}"
    )
