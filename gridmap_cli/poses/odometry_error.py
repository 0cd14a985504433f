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
from dataclasses import asdict, dataclass, fields
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
#: The newest version read and written: version 2 adds :data:`VERSION_2_KEYS`.
LATEST_VERSION = 2
VERSION_2_KEYS = ("lateral_m_per_sqrt_m", "heading_rad_per_sqrt_m")

#: The Polaroid 6500 ranging module's stated accuracy, +-1 % of the range (seed paper, sec. 4).
DEFAULT_SONAR_RELATIVE_ERROR = 0.01


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

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"{f.name} must be a number, got {value!r}")
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{f.name} must be a finite number >= 0, got {float(value)}")

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
_KEYS_V1 = tuple(k for k in _KEYS if k not in VERSION_2_KEYS)


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
    if isinstance(version, bool) or version not in (FORMAT_VERSION, LATEST_VERSION):
        raise InputFileError(
            path,
            f"unsupported {FORMAT_KEY} version {version!r} "
            f"(this gridmap reads {FORMAT_VERSION} and {LATEST_VERSION})",
            line=lines.get(FORMAT_KEY),
        )
    known = _KEYS if version == LATEST_VERSION else _KEYS_V1
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
        if not (math.isfinite(parsed) and parsed >= 0.0):
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
    # version 1 while the version-2 terms are 0: older gridmaps read the file as before
    v2 = any(values[k] for k in VERSION_2_KEYS)
    body = [f"{FORMAT_KEY}: {LATEST_VERSION if v2 else FORMAT_VERSION}"]
    for key, value in values.items():
        if v2 or key not in VERSION_2_KEYS:
            body.append(f"{key}: {format_float(value)}")
    return "\n".join([*head, *body]) + "\n"


def save_odometry_error(
    model: OdometryError, path: Path, comments: list[str] | None = None
) -> None:
    """Write ``model`` to ``path`` atomically (see :func:`odometry_error_yaml`)."""
    text = odometry_error_yaml(model, comments)
    with atomic_output(Path(path)) as tmp:
        tmp.write_text(text, encoding="utf-8")
