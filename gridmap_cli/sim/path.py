"""Path files for the simulator, and the true trajectory a robot drives along one.

A path file is YAML::

    # gridmap path file, version 1
    gridmap-path: 1
    waypoints:              # world frame, metres; at least two, consecutive ones distinct
      - [2.0, 14.5]
      - [38.0, 14.5]
      - [38.0, 15.0]
    speed_m_s: 0.4          # driving speed, > 0 (default 0.4)
    turn_rate_deg_s: 40     # in-place turn rate, > 0 (default 40)
    laps: 1                 # times round the path, integer >= 1 (default 1)
    closed: false           # drive back to the first waypoint at the end (default false)
    start_heading_deg: 0    # heading at the start, world frame, counter-clockwise from +x
                            # (default: towards the second waypoint)

Only these keys are allowed. The path is closed (the robot drives from the last waypoint back to
the first) when ``closed: true`` or ``laps > 1``; ``closed: false`` with ``laps > 1`` is refused as
contradictory. A last waypoint equal to the first closes the path by itself.

The robot is a differential drive that moves like a Pioneer under a waypoint script: at the start
and at every waypoint it turns in place (the shorter way round) at ``turn_rate_deg_s`` until it
faces the next waypoint, then drives straight to it at ``speed_m_s``. Speed changes are
instantaneous; a simulation does not need acceleration ramps to exercise a mapper. At the end of
the last lap the robot stops at the last waypoint it drove to, facing the way it came.
"""

from __future__ import annotations

import io
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import numpy as np
import numpy.typing as npt
import yaml

from gridmap_cli.errors import InputFileError, SimulationSizeError
from gridmap_cli.geometry import wrap_angle
from gridmap_cli.limits import read_settings_text
from gridmap_cli.records import PoseTrack
from gridmap_cli.yamlfile import yaml_problem

FloatArray = npt.NDArray[np.float64]

DEFAULT_SPEED_M_S = 0.4
DEFAULT_TURN_RATE_DEG_S = 40.0
#: The most poses one simulation samples: 5 M poses is 139 hours at 10 Hz, and a few hundred MB
#: of arrays; beyond it numpy fails to allocate, or the machine swaps.
MAX_SIM_POSES = 5_000_000

_KEYS = (
    "gridmap-path",
    "waypoints",
    "speed_m_s",
    "turn_rate_deg_s",
    "laps",
    "closed",
    "start_heading_deg",
)


@dataclass(frozen=True)
class WaypointPath:
    """A parsed path file.

    ``waypoints``: shape (K, 2), K >= 2, world frame, metres; consecutive rows distinct and, for a
    closed path, the last row differs from the first (closing is implied, not stored).
    ``start_heading_rad``: heading at t = 0 (world frame), or None for "towards waypoint 2".
    """

    waypoints: FloatArray
    speed_m_s: float = DEFAULT_SPEED_M_S
    turn_rate_rad_s: float = math.radians(DEFAULT_TURN_RATE_DEG_S)
    laps: int = 1
    closed: bool = False
    start_heading_rad: float | None = None
    source: str = "<path>"


def load_path(source: str | Path | TextIO) -> WaypointPath:
    """Read a path file from a file name or an open text handle."""
    if isinstance(source, str | Path):
        try:
            text = read_settings_text(Path(source), "a path file")
        except (OSError, UnicodeDecodeError) as exc:
            raise InputFileError(source, f"cannot read: {exc}") from exc
        return parse_path_yaml(text, str(source))
    name = getattr(source, "name", "<path>")
    return parse_path_yaml(source.read(), str(name))


def parse_path_yaml(text: str, source: str) -> WaypointPath:
    """Parse path-file YAML text; ``source`` names it in error messages (``path:line: ...``)."""
    try:
        # compose for the line numbers of entries, safe_load for the values
        node = yaml.compose(io.StringIO(text))
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        line, problem = yaml_problem(exc)
        raise InputFileError(source, problem, line) from exc
    if not isinstance(doc, dict) or not isinstance(node, yaml.MappingNode):
        raise InputFileError(source, "expected a mapping with 'gridmap-path: 1' and 'waypoints'")
    key_lines = {
        str(k.value): k.start_mark.line + 1 for k, _ in node.value if isinstance(k, yaml.ScalarNode)
    }
    for key in doc:
        if key not in _KEYS:
            raise InputFileError(
                source,
                f"unknown key {key!r} (known: {', '.join(_KEYS)})",
                key_lines.get(str(key)),
            )
    version = doc.get("gridmap-path")
    if version != 1 or isinstance(version, bool):
        found = "it is missing" if version is None else f"got {version!r}"
        raise InputFileError(
            source,
            f"expected 'gridmap-path: 1' (format version), {found}",
            key_lines.get("gridmap-path"),
        )

    def line_of(key: str) -> int | None:
        return key_lines.get(key)

    waypoints = _waypoints(source, doc.get("waypoints"), _entry_lines(node, "waypoints"), line_of)
    speed = _positive(source, "speed_m_s", doc.get("speed_m_s", DEFAULT_SPEED_M_S), line_of)
    turn = _positive(
        source, "turn_rate_deg_s", doc.get("turn_rate_deg_s", DEFAULT_TURN_RATE_DEG_S), line_of
    )
    laps = doc.get("laps", 1)
    if isinstance(laps, bool) or not isinstance(laps, int) or laps < 1:
        raise InputFileError(
            source, f"'laps' must be an integer >= 1, got {laps!r}", line_of("laps")
        )
    closed_raw = doc.get("closed")
    if closed_raw is not None and not isinstance(closed_raw, bool):
        raise InputFileError(
            source, f"'closed' must be true or false, got {closed_raw!r}", line_of("closed")
        )
    if closed_raw is False and laps > 1:
        raise InputFileError(
            source,
            f"'closed: false' contradicts 'laps: {laps}' (laps need a closed path)",
            line_of("closed"),
        )
    closed = bool(closed_raw) or laps > 1
    if np.array_equal(waypoints[-1], waypoints[0]) and waypoints.shape[0] > 2:
        # the file draws the closing leg itself
        waypoints = waypoints[:-1]
        closed = True
    start = doc.get("start_heading_deg")
    start_rad = None
    if start is not None:
        start_rad = math.radians(_finite(source, "start_heading_deg", start, line_of))
    return WaypointPath(
        waypoints=waypoints,
        speed_m_s=speed,
        turn_rate_rad_s=math.radians(turn),
        laps=laps,
        closed=closed,
        start_heading_rad=start_rad,
        source=source,
    )


def _entry_lines(node: yaml.MappingNode, key: str) -> list[int]:
    """1-based lines of the entries of the top-level list ``key`` (empty if it is no list)."""
    for k, value in node.value:
        if getattr(k, "value", None) == key and isinstance(value, yaml.SequenceNode):
            return [item.start_mark.line + 1 for item in value.value]
    return []


def _finite(source: str, what: str, value: Any, line_of: Callable[[str], int | None]) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputFileError(
            source, f"'{what}' must be a finite number, got {value!r}", line_of(what)
        )
    return float(value)


def _positive(source: str, what: str, value: Any, line_of: Callable[[str], int | None]) -> float:
    out = _finite(source, what, value, line_of)
    if out <= 0.0:
        raise InputFileError(source, f"'{what}' must be > 0, got {value!r}", line_of(what))
    return out


def _waypoints(
    source: str, raw: Any, lines: list[int], line_of: Callable[[str], int | None]
) -> FloatArray:
    if not isinstance(raw, list) or len(raw) < 2:
        raise InputFileError(
            source, "'waypoints' must be a list of at least two [x, y] pairs", line_of("waypoints")
        )
    points: list[tuple[float, float]] = []
    for i, entry in enumerate(raw):
        line = lines[i] if i < len(lines) else None
        ok = (
            isinstance(entry, list)
            and len(entry) == 2
            and all(
                not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)
                for v in entry
            )
        )
        if not ok:
            raise InputFileError(
                source, f"waypoint {i + 1} must be [x, y] in metres, got {entry!r}", line
            )
        point = (float(entry[0]), float(entry[1]))
        if points and point == points[-1]:
            raise InputFileError(source, f"waypoint {i + 1} repeats waypoint {i}", line)
        points.append(point)
    return np.asarray(points, dtype=np.float64)


@dataclass(frozen=True)
class _Motion:
    """A sequence of motion primitives, shape (P,) each, back to back in time.

    Primitive k starts at ``t0_s[k]`` at pose (``x_m``, ``y_m``, ``theta_rad``) and lasts
    ``dur_s[k]``; it moves at ``v_m_s`` along its heading and turns at ``w_rad_s`` (one of the two
    is zero).
    """

    t0_s: FloatArray
    dur_s: FloatArray
    x_m: FloatArray
    y_m: FloatArray
    theta_rad: FloatArray
    v_m_s: FloatArray
    w_rad_s: FloatArray

    @property
    def total_s(self) -> float:
        return float(self.t0_s[-1] + self.dur_s[-1]) if self.t0_s.shape[0] else 0.0

    def at(self, t_s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Poses at times ``t_s`` (shape (N,), within [0, total_s]): x, y, theta, shape (N,)."""
        k = np.clip(np.searchsorted(self.t0_s, t_s, side="right") - 1, 0, self.t0_s.shape[0] - 1)
        tau = np.clip(t_s - self.t0_s[k], 0.0, self.dur_s[k])
        th = self.theta_rad[k]
        dist = self.v_m_s[k] * tau
        return (
            self.x_m[k] + dist * np.cos(th),
            self.y_m[k] + dist * np.sin(th),
            wrap_angle(th + self.w_rad_s[k] * tau),
        )


def _motion(path: WaypointPath, start_heading: float, legs: FloatArray) -> tuple[_Motion, float]:
    """Turn-then-drive primitives along ``legs`` (shape (L+1, 2): L legs) from ``start_heading``.

    Returns the primitives and the heading at the end.
    """
    t0: list[float] = []
    dur: list[float] = []
    xs: list[float] = []
    ys: list[float] = []
    ths: list[float] = []
    vs: list[float] = []
    ws: list[float] = []
    t = 0.0
    heading = start_heading
    for (x0, y0), (x1, y1) in itertools.pairwise(legs):
        target = math.atan2(y1 - y0, x1 - x0)
        turn = float(wrap_angle(target - heading))
        if turn != 0.0:
            d = abs(turn) / path.turn_rate_rad_s
            t0.append(t)
            dur.append(d)
            xs.append(x0)
            ys.append(y0)
            ths.append(heading)
            vs.append(0.0)
            ws.append(math.copysign(path.turn_rate_rad_s, turn))
            t += d
        heading = target
        d = math.hypot(x1 - x0, y1 - y0) / path.speed_m_s
        t0.append(t)
        dur.append(d)
        xs.append(x0)
        ys.append(y0)
        ths.append(heading)
        vs.append(path.speed_m_s)
        ws.append(0.0)
        t += d
    arrays = (np.asarray(v, dtype=np.float64) for v in (t0, dur, xs, ys, ths, vs, ws))
    return _Motion(*arrays), heading


def trajectory(
    path: WaypointPath,
    rate_hz: float,
    duration_s: float | None = None,
    max_poses: int = MAX_SIM_POSES,
    what_limits: str = "MAX_SIM_POSES",
) -> PoseTrack:
    """The true poses of a robot driving ``path``, sampled at ``rate_hz`` from t = 0.

    Parameters
    ----------
    path
        The path to drive.
    rate_hz
        Sampling rate; sample k is at t = k / rate_hz, stamped ``round(k * 1e9 / rate_hz)`` ns.
    duration_s
        None: drive ``path.laps`` laps and stop; the last sample is the last one at or before the
        end. A number: keep lapping (closing the path back to the first waypoint even if the file
        does not, so that laps can follow each other) and return the samples with t < duration_s,
        e.g. 36,000 poses for one hour at 10 Hz; ``path.laps`` is then ignored.
    max_poses, what_limits
        More poses than ``max_poses`` raise :class:`SimulationSizeError` (naming
        ``what_limits``) before any array is allocated.

    Returns
    -------
    PoseTrack
        Shape (N,): robot base poses in the world frame, theta wrapped to [-pi, pi).
    """
    if not (rate_hz > 0.0 and math.isfinite(rate_hz)):
        raise ValueError(f"rate_hz must be a positive number, got {rate_hz}")
    if duration_s is not None and not (duration_s > 0.0 and math.isfinite(duration_s)):
        raise ValueError(f"duration_s must be a positive number of seconds, got {duration_s}")
    wp = path.waypoints
    closed = path.closed or duration_s is not None
    lap = np.vstack([wp, wp[:1]]) if closed else wp
    first_leg = math.atan2(wp[1, 1] - wp[0, 1], wp[1, 0] - wp[0, 0])
    start = first_leg if path.start_heading_rad is None else path.start_heading_rad
    first, end_heading = _motion(path, start, lap)
    # Later laps start facing along the closing leg, so their first turn differs from lap one's.
    later, _ = _motion(path, end_heading, lap)
    if duration_s is not None:
        wanted = max(duration_s * rate_hz, 1.0)
    else:
        total = first.total_s + (path.laps - 1) * later.total_s
        wanted = total * rate_hz + 1.0
    if not wanted <= max_poses:  # also NaN and inf, from paths of absurd coordinates
        raise SimulationSizeError(
            f"{path.source}: driving it "
            + (f"for {duration_s:g} s" if duration_s is not None else f"{path.laps} lap(s)")
            + f" at {rate_hz:g} Hz gives {wanted:.3g} poses, above gridmap's limit of "
            f"{max_poses:,} for this simulation ({what_limits}); lower the rate or the duration"
        )
    if duration_s is not None:
        n = max(math.ceil(duration_s * rate_hz - 1e-9), 1)
    else:
        n = math.floor(total * rate_hz + 1e-9) + 1
    k = np.arange(n, dtype=np.int64)
    t_s = k / rate_hz
    x = np.empty(n)
    y = np.empty(n)
    th = np.empty(n)
    in_first = t_s <= first.total_s
    x[in_first], y[in_first], th[in_first] = first.at(t_s[in_first])
    rest = ~in_first
    if rest.any():
        # fmod keeps the time within a lap; a sample exactly at a lap boundary is the end of the
        # previous lap's arrival and the start of the next lap's turn: the same pose either way
        tau = np.fmod(t_s[rest] - first.total_s, later.total_s)
        x[rest], y[rest], th[rest] = later.at(tau)
    stamp = np.round(k * (1e9 / rate_hz)).astype(np.int64)
    return PoseTrack(stamp_ns=stamp, x_m=x, y_m=y, theta_rad=th)
