"""Pose tracks as files that trajectory tools read: TUM (what evo reads) and CSV.

TUM: one line per pose, ``timestamp x y z qx qy qz qw``, space-separated, timestamp in seconds,
the planar pose as z = 0 and a rotation about z. CSV: a header ``time,x,y,theta`` (seconds,
metres, radians) and, when per-pose outcomes are given (scan matching), a ``status`` column.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from gridmap_cli.atomic import atomic_write
from gridmap_cli.errors import UsageError
from gridmap_cli.records import PoseTrack
from gridmap_cli.writers.csv_log import ns_to_seconds_text

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


def write_trajectory(path: Path, track: PoseTrack, status: Sequence[str] | None = None) -> None:
    """Write ``track`` to ``path`` (format by extension) atomically."""
    text = trajectory_text(track, trajectory_format(path), status)
    with atomic_write(path, "the trajectory") as tmp:
        tmp.write_text(text, encoding="utf-8")
