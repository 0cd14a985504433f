"""Pose tracks as files that trajectory tools read: TUM (what evo reads) and CSV.

TUM: one line per pose, ``timestamp x y z qx qy qz qw``, space-separated, timestamp in seconds,
the planar pose as z = 0 and a rotation about z. CSV: a header ``time,x,y,theta`` (seconds,
metres, radians) and, when per-pose outcomes are given (scan matching), a ``status`` column.

Covariance CSV (``--pose slam``, beside the track: :func:`covariance_path`): a header
``time,xx,xy,xtheta,yy,ytheta,thetatheta,keyframe`` and one row per pose of the track, the same
stamps in the same order: the upper triangle of the 3 x 3 covariance of (x, y, theta) in the map
frame (m^2, m rad, rad^2), and 1 where the pose is a node of the pose graph (its marginal), 0
where it lies between two (the two marginals mixed linearly in time).
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from gridmap_cli.atomic import atomic_outputs, atomic_write
from gridmap_cli.errors import GridmapError, UsageError
from gridmap_cli.records import PoseTrack
from gridmap_cli.writers.csv_log import ns_to_seconds_text

#: Header of the covariance CSV.
COVARIANCE_HEADER = "time,xx,xy,xtheta,yy,ytheta,thetatheta,keyframe"
#: Output format by file extension.
TRAJECTORY_FORMATS = {".tum": "tum", ".txt": "tum", ".csv": "csv"}


def trajectory_format(path: Path) -> str:
    """The format ``path``'s extension asks for; :class:`UsageError` for any other."""
    fmt = TRAJECTORY_FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise UsageError(
            f"{path}: a trajectory is written as .tum (TUM, what evo reads) or .csv, "
            f"not {path.suffix or 'no extension'}"
        )
    return fmt


def trajectory_text(track: PoseTrack, fmt: str, status: Sequence[str] | None = None) -> str:
    """The track as TUM or CSV text (see the module docstring)."""
    out = io.StringIO()
    half = 0.5 * track.theta_rad
    qz, qw = np.sin(half), np.cos(half)
    if fmt == "csv":
        out.write("time,x,y,theta" + (",status" if status is not None else "") + "\n")
    for k in range(len(track)):
        t = ns_to_seconds_text(int(track.stamp_ns[k]))
        x, y, th = float(track.x_m[k]), float(track.y_m[k]), float(track.theta_rad[k])
        if fmt == "tum":
            out.write(f"{t} {x!r} {y!r} 0 0 0 {float(qz[k])!r} {float(qw[k])!r}\n")
        else:
            extra = f",{status[k]}" if status is not None else ""
            out.write(f"{t},{x!r},{y!r},{th!r}{extra}\n")
    return out.getvalue()


def write_trajectory(
    path: Path,
    track: PoseTrack,
    status: Sequence[str] | None = None,
    covariance: tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_]] | None = None,
) -> None:
    """Write ``track`` to ``path`` (format by extension) atomically; with ``covariance``
    (``(cov (N, 3, 3), keyframe (N,))`` at the track's poses) also the covariance CSV at
    :func:`covariance_path`, both or neither."""
    text = trajectory_text(track, trajectory_format(path), status)
    if covariance is None:
        with atomic_write(path, "the trajectory") as tmp:
            tmp.write_text(text, encoding="utf-8")
        return
    cov_path = covariance_path(path)
    cov_text = covariance_text(track.stamp_ns, *covariance)
    try:
        with atomic_outputs([path, cov_path]) as (tmp, cov_tmp):
            tmp.write_text(text, encoding="utf-8")
            cov_tmp.write_text(cov_text, encoding="utf-8")
    except OSError as exc:
        raise GridmapError(
            f"{path}: cannot write the trajectory and its covariance: {exc.strerror or exc}"
        ) from exc


def covariance_path(track_path: Path) -> Path:
    """Where the covariance of the track written to ``track_path`` goes: ``track.tum`` ->
    ``track.cov.csv`` beside it."""
    return track_path.with_name(f"{track_path.stem}.cov.csv")


def covariance_text(
    stamp_ns: npt.NDArray[np.int64], cov: npt.NDArray[np.float64], keyframe: npt.NDArray[np.bool_]
) -> str:
    """The covariance CSV (module docstring): ``stamp_ns`` (N,), ``cov`` (N, 3, 3),
    ``keyframe`` (N,)."""
    out = io.StringIO()
    out.write(COVARIANCE_HEADER + "\n")
    for k in range(len(stamp_ns)):
        c = cov[k]
        cells = (c[0, 0], c[0, 1], c[0, 2], c[1, 1], c[1, 2], c[2, 2])
        values = ",".join(repr(float(v)) for v in cells)
        out.write(f"{ns_to_seconds_text(int(stamp_ns[k]))},{values},{int(keyframe[k])}\n")
    return out.getvalue()
