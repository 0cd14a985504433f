"""Tiny CARMEN log lines for the tests, written as CARMEN's logger writes them."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

Pose = tuple[float, float, float]

HEADER = (
    "# CARMEN Logfile\n"
    "# message formats defined: PARAM SYNC ODOM FLASER RLASER TRUEPOS\n"
    "PARAM robot_frontlaser_offset 0.0 nohost 0\n"
)


def _p(pose: Pose) -> str:
    return " ".join(f"{v:.9f}" for v in pose)


def _t(stamp_s: float) -> str:
    return f"{stamp_s:.6f} host {stamp_s:.6f}"


def odom(pose: Pose, stamp_s: float) -> str:
    return f"ODOM {_p(pose)} 0 0 0 {_t(stamp_s)}"


def flaser(ranges: Sequence[float], pose: Pose, stamp_s: float, name: str = "FLASER") -> str:
    values = " ".join(f"{r:g}" for r in ranges)
    return f"{name} {len(ranges)} {values} {_p(pose)} {_p(pose)} {_t(stamp_s)}"


def truepos(true: Pose, odo: Pose, stamp_s: float) -> str:
    return f"TRUEPOS {_p(true)} {_p(odo)} {_t(stamp_s)}"


def robotlaser(
    ranges: Sequence[float],
    pose: Pose,
    stamp_s: float,
    start: float = -1.5707963,
    res: float = 0.0174533,
    max_range: float = 30.0,
    number: int = 1,
) -> str:
    values = " ".join(f"{r:g}" for r in ranges)
    fov = res * (len(ranges) - 1)
    return (
        f"ROBOTLASER{number} 0 {start} {fov} {res} {max_range} 0.01 0 {len(ranges)} {values} "
        f"2 0.5 0.5 {_p(pose)} {_p(pose)} 0.1 0.0 0.5 0.2 0.0 {_t(stamp_s)}"
    )


def rawlaser(
    ranges: Sequence[float], stamp_s: float, number: int = 1, max_range: float = 30.0
) -> str:
    values = " ".join(f"{r:g}" for r in ranges)
    return (
        f"RAWLASER{number} 0 -1.5707963 3.1415926 0.0174533 {max_range} 0.01 0 {len(ranges)} "
        f"{values} 0 {_t(stamp_s)}"
    )


def write(
    tmp_path: Path, lines: Sequence[str], name: str = "run.log", header: str = HEADER
) -> Path:
    path = tmp_path / name
    path.write_text(header + "\n".join(lines) + "\n")
    return path
