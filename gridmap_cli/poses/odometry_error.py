"""How far odometry can be trusted after it has driven and turned: the seed paper's f and g.

The seed paper's eq. 11 and 12 widen each sonar reading by what the odometry has done since the
log started: sigma_z = k z + f, sigma_theta = beta / 2 + g. gridmap models

    f(d)      = range_m_per_m * d + range_m_per_sqrt_m * sqrt(d)                      [m]
    g(d, phi) = bearing_rad_per_rad * phi + bearing_rad_per_sqrt_rad * sqrt(phi)
                + heading_drift_rad_per_m * d                                         [rad]

with d the distance travelled (metres) and phi the absolute rotation accumulated (radians), both
as the odometry reports them, counted from the first pose of the log. The linear terms are the
systematic errors (a distance scale off by a few per cent, a turn scale off, unequal wheels that
curve every straight); the square-root terms are random walks, whose spread grows with the
square root of what was driven. ``docs/odometry-error.md`` describes the YAML file format;
``schemas/odometry-error.schema.json`` is its JSON Schema.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.atomic import atomic_output
from gridmap_cli.errors import InputFileError
from gridmap_cli.geometry import wrap_angle
from gridmap_cli.records import PoseTrack
from gridmap_cli.yamlfile import format_float, number, read_yaml_mapping

FloatArray = npt.NDArray[np.float64]

#: Key and value that open an odometry-error file.
FORMAT_KEY = "gridmap-odometry-error"
FORMAT_VERSION = 1
#: The newest version read and written: version 2 adds :data:`VERSION_2_KEYS`, version 3
#: :data:`VERSION_3_KEYS`.
LATEST_VERSION = 3
VERSION_2_KEYS = ("lateral_m_per_sqrt_m", "heading_rad_per_sqrt_m")
#: The signed systematic errors ``build --correct-odometry`` takes out of the track (the only
#: keys that may be negative).
BIAS_KEYS = ("distance_scale_bias", "turn_scale_bias", "heading_drift_bias_rad_per_m")
VERSION_3_KEYS = BIAS_KEYS

#: The Polaroid 6500 ranging module's stated accuracy, +-1 % of the range (seed paper, sec. 4).
DEFAULT_SONAR_RELATIVE_ERROR = 0.01
#: A scale bias of -1 would mean the odometry reports no motion at all: biases stay inside +-0.5.
MAX_BIAS = 0.5


@dataclass(frozen=True)
class OdometryError:
    """Coefficients of f and g (module docstring), all finite and >= 0.

    Attributes
    ----------
    range_m_per_m
        Systematic range spread per metre driven (m/m): the odometry's distance scale error.
    range_m_per_sqrt_m
        Random-walk range spread (m/sqrt(m)): standard deviation of the distance error after 1 m.
    bearing_rad_per_rad
        Systematic bearing spread per radian turned (rad/rad): the turn scale error.
    bearing_rad_per_sqrt_rad
        Random-walk bearing spread (rad/sqrt(rad)): standard deviation of the heading error
        after turning 1 rad.
    heading_drift_rad_per_m
        Heading drift per metre driven (rad/m): unequal wheels curving every straight.
    lateral_m_per_sqrt_m
        Version 2: random-walk lateral position error (m/sqrt(m)), across the direction driven.
    heading_rad_per_sqrt_m
        Version 2: random-walk heading error with the distance driven (rad/sqrt(m)).
    distance_scale_bias, turn_scale_bias, heading_drift_bias_rad_per_m
        Version 3, signed: the systematic errors themselves, as calibrate measured them. The
        odometry reports (1 + distance_scale_bias) m per true metre, (1 + turn_scale_bias) rad
        per true radian, and turns heading_drift_bias_rad_per_m (counter-clockwise positive)
        more than the truth per metre driven. ``build --correct-odometry`` takes them out.
    sonar_relative_error
        k of eq. 11, the sonar's own relative range error (0.01: 1 %, the Polaroid 6500).
    """

    range_m_per_m: float = 0.0
    range_m_per_sqrt_m: float = 0.0
    bearing_rad_per_rad: float = 0.0
    bearing_rad_per_sqrt_rad: float = 0.0
    heading_drift_rad_per_m: float = 0.0
    sonar_relative_error: float = DEFAULT_SONAR_RELATIVE_ERROR
    lateral_m_per_sqrt_m: float = 0.0
    heading_rad_per_sqrt_m: float = 0.0
    distance_scale_bias: float = 0.0
    turn_scale_bias: float = 0.0
    heading_drift_bias_rad_per_m: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"{f.name} must be a number, got {value!r}")
            if f.name in BIAS_KEYS:
                if not (math.isfinite(value) and abs(value) < MAX_BIAS):
                    raise ValueError(
                        f"{f.name} must be a finite number between -{MAX_BIAS:g} and "
                        f"{MAX_BIAS:g}, got {float(value)}"
                    )
            elif not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{f.name} must be a finite number >= 0, got {float(value)}")

    @property
    def has_bias(self) -> bool:
        """Whether any signed systematic error (version 3) is known."""
        return any(getattr(self, k) for k in BIAS_KEYS)

    def random_part(self) -> OdometryError:
        """The model of the track once its biases are corrected: the random walks and k alone.
        (Keeping the halves' disagreement on the biases as a systematic spread measured worse
        on the CARMEN logs: docs/odometry-error.md.)"""
        return replace(
            self,
            range_m_per_m=0.0,
            bearing_rad_per_rad=0.0,
            heading_drift_rad_per_m=0.0,
            **{k: 0.0 for k in BIAS_KEYS},
        )

    def f(self, distance_m: npt.ArrayLike) -> FloatArray:
        """Range spread (metres) after ``distance_m`` metres driven; any shape, same shape out."""
        d = np.maximum(np.asarray(distance_m, dtype=np.float64), 0.0)
        return np.asarray(self.range_m_per_m * d + self.range_m_per_sqrt_m * np.sqrt(d))

    def g(self, distance_m: npt.ArrayLike, rotation_rad: npt.ArrayLike) -> FloatArray:
        """Bearing spread (radians) after driving ``distance_m`` and turning ``rotation_rad``.

        ``rotation_rad`` is the absolute rotation accumulated (>= 0); inputs broadcast together.
        """
        d = np.maximum(np.asarray(distance_m, dtype=np.float64), 0.0)
        phi = np.maximum(np.asarray(rotation_rad, dtype=np.float64), 0.0)
        return np.asarray(
            self.bearing_rad_per_rad * phi
            + self.bearing_rad_per_sqrt_rad * np.sqrt(phi)
            + self.heading_drift_rad_per_m * d
        )

    def sigma_range(self, range_m: npt.ArrayLike, distance_m: npt.ArrayLike) -> FloatArray:
        """Eq. 11: sigma_z = k z + f(d), metres; inputs broadcast together."""
        z = np.asarray(range_m, dtype=np.float64)
        return np.asarray(self.sonar_relative_error * z + self.f(distance_m))

    def sigma_bearing(
        self, beam_width_rad: npt.ArrayLike, distance_m: npt.ArrayLike, rotation_rad: npt.ArrayLike
    ) -> FloatArray:
        """Eq. 12: sigma_theta = beta / 2 + g(d, phi), radians; inputs broadcast together."""
        beta = np.asarray(beam_width_rad, dtype=np.float64)
        return np.asarray(beta / 2.0 + self.g(distance_m, rotation_rad))

    def as_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}


def travelled(track: PoseTrack) -> tuple[FloatArray, FloatArray]:
    """Distance driven and absolute rotation accumulated at each pose of ``track``.

    Returns ``(distance_m, rotation_rad)``, each shape (N,), starting at 0 at the first pose:
    the running sums of the straight-line step lengths and of the absolute wrapped heading
    increments between consecutive poses. Steps are assumed to turn less than pi, which any log
    sampled faster than a robot spins satisfies.
    """
    n = len(track)
    if n == 0:
        return np.zeros(0), np.zeros(0)
    step = np.hypot(np.diff(track.x_m), np.diff(track.y_m))
    turn = np.abs(wrap_angle(np.diff(track.theta_rad)))
    return (
        np.concatenate([[0.0], np.cumsum(step)]),
        np.concatenate([[0.0], np.cumsum(turn)]),
    )


def travelled_at(
    track: PoseTrack,
    stamp_ns: npt.NDArray[np.int64],
    sums: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[FloatArray, FloatArray]:
    """:func:`travelled` interpolated linearly in time at ``stamp_ns`` (shape (M,)).

    Stamps before the track's first (after its last) stamp get the first (last) values.
    ``sums``: :func:`travelled` of ``track``, for a caller that asks again and again (build's
    chunks): the running sums are then not made afresh over the whole track each time, and
    only the poses around ``stamp_ns`` (sorted) are looked at, which gives the same values.
    """
    if len(track) == 0:
        raise ValueError("the track holds no pose")
    distance, rotation = travelled(track) if sums is None else sums
    stamps = np.asarray(stamp_ns)
    part = slice(None)
    if sums is not None and stamps.shape[0] > 0:
        # np.interp takes each value from the two poses around it, and clamps at the ends
        lo = max(int(np.searchsorted(track.stamp_ns, stamps[0], "right")) - 1, 0)
        hi = int(np.searchsorted(track.stamp_ns, stamps[-1], "left")) + 1
        part = slice(lo, hi)
    t = (track.stamp_ns[part] - track.stamp_ns[0]).astype(np.float64)
    q = (stamps - track.stamp_ns[0]).astype(np.float64)
    return np.interp(q, t, distance[part]), np.interp(q, t, rotation[part])


_KEYS = tuple(f.name for f in fields(OdometryError))
#: The keys each version knows.
_KNOWN = {
    1: tuple(k for k in _KEYS if k not in VERSION_2_KEYS + VERSION_3_KEYS),
    2: tuple(k for k in _KEYS if k not in VERSION_3_KEYS),
    3: _KEYS,
}


def load_odometry_error(path: Path) -> OdometryError:
    """Read an odometry-error YAML file (``docs/odometry-error.md``).

    Keys left out take their defaults (0 for the f and g coefficients, 0.01 for
    ``sonar_relative_error``). Raises :class:`InputFileError`, naming the line where known, for
    a missing or unreadable file, invalid YAML, a missing or wrong format version, unknown keys,
    and values that are not finite numbers >= 0.
    """
    path = Path(path)
    doc, lines = read_yaml_mapping(
        path,
        "an odometry-error file",
        f"expected a mapping with '{FORMAT_KEY}: {FORMAT_VERSION}'",
    )
    version = doc.get(FORMAT_KEY)
    if FORMAT_KEY not in doc:
        raise InputFileError(path, f"missing '{FORMAT_KEY}: {FORMAT_VERSION}' (format version)")
    if isinstance(version, bool) or version not in _KNOWN:
        raise InputFileError(
            path,
            f"unsupported {FORMAT_KEY} version {version!r} "
            f"(this gridmap reads {', '.join(str(v) for v in _KNOWN)})",
            line=lines.get(FORMAT_KEY),
        )
    known = _KNOWN[version]
    values: dict[str, Any] = {}
    for key, value in doc.items():
        if key == FORMAT_KEY:
            continue
        if key not in known:
            raise InputFileError(
                path,
                f"unknown key {key!r} in version {version} (known: {', '.join(known)})",
                line=lines.get(key),
            )
        parsed = number(value)
        if parsed is None:
            raise InputFileError(
                path, f"{key} must be a number, got {value!r}", line=lines.get(key)
            )
        if key in BIAS_KEYS:
            if not (math.isfinite(parsed) and abs(parsed) < MAX_BIAS):
                raise InputFileError(
                    path,
                    f"{key} must be a finite number between -{MAX_BIAS:g} and {MAX_BIAS:g}, "
                    f"got {value!r}",
                    line=lines.get(key),
                )
        elif not (math.isfinite(parsed) and parsed >= 0.0):
            raise InputFileError(
                path, f"{key} must be a finite number >= 0, got {value!r}", line=lines.get(key)
            )
        values[key] = parsed
    return OdometryError(**values)


def odometry_error_yaml(model: OdometryError, comments: list[str] | None = None) -> str:
    """The file text for ``model``: version line, then every key, values in full precision.

    ``comments`` become ``#`` lines at the top (where a calibration came from).
    """
    head = [f"# {c}" if c else "#" for c in comments or []]
    values = model.as_dict()
    # the lowest version that holds the terms used: older gridmaps read the file as before
    version = (
        3
        if any(values[k] for k in VERSION_3_KEYS)
        else 2
        if any(values[k] for k in VERSION_2_KEYS)
        else 1
    )
    body = [f"{FORMAT_KEY}: {version}"]
    for key, value in values.items():
        if key in _KNOWN[version]:
            body.append(f"{key}: {format_float(value)}")
    return "\n".join([*head, *body]) + "\n"


def save_odometry_error(
    model: OdometryError, path: Path, comments: list[str] | None = None
) -> None:
    """Write ``model`` to ``path`` atomically (see :func:`odometry_error_yaml`)."""
    text = odometry_error_yaml(model, comments)
    with atomic_output(Path(path)) as tmp:
        tmp.write_text(text, encoding="utf-8")


def correct_track(track: PoseTrack, model: OdometryError) -> PoseTrack:
    """``track`` with the model's signed systematic errors (version 3) taken out.

    Each step between consecutive poses, in the robot frame of the pose it starts from, is
    turned back into what the robot truly did: its translation divided by
    (1 + distance_scale_bias), its wrapped turn less heading_drift_bias_rad_per_m times the
    corrected step length, divided by (1 + turn_scale_bias); the steps are then composed again
    from the first pose, which is kept. Same stamps, shape (N,); a model without biases gives
    ``track`` itself.
    """
    if not model.has_bias or len(track) < 2:
        return track
    th = track.theta_rad
    c, s = np.cos(th[:-1]), np.sin(th[:-1])
    ex, ey = np.diff(track.x_m), np.diff(track.y_m)
    dx = (c * ex + s * ey) / (1.0 + model.distance_scale_bias)
    dy = (-s * ex + c * ey) / (1.0 + model.distance_scale_bias)
    dth = wrap_angle(np.diff(th))
    dth = (dth - model.heading_drift_bias_rad_per_m * np.hypot(dx, dy)) / (
        1.0 + model.turn_scale_bias
    )
    heading = th[0] + np.concatenate([[0.0], np.cumsum(dth)])
    # the translation leaves along the corrected heading of the pose it starts from
    cc, sc = np.cos(heading[:-1]), np.sin(heading[:-1])
    x = track.x_m[0] + np.concatenate([[0.0], np.cumsum(cc * dx - sc * dy)])
    y = track.y_m[0] + np.concatenate([[0.0], np.cumsum(sc * dx + cc * dy)])
    theta = wrap_angle(heading)
    theta[0] = th[0]  # the first pose is kept to the bit
    return PoseTrack(track.stamp_ns, x, y, theta)
