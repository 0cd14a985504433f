"""Small text helpers every section of ``gridmap inspect``'s text output shares.

Counts with thousands separators, rates, lengths, poses, lists cut short and aligned tables.
"""

from __future__ import annotations

import math


def some(items: list[str], limit: int) -> str:
    """The first ``limit`` items, comma-separated, and how many more there are."""
    more = f" and {len(items) - limit} more" if len(items) > limit else ""
    return ", ".join(items[:limit]) + more


def ends(names: tuple[str, ...]) -> list[str]:
    """A long list of names as its first, ``..`` and its last."""
    if len(names) <= 3:
        return list(names)
    return [names[0], "..", names[-1]]


def number(value: int) -> str:
    """A count with thousands separators (12,345)."""
    return f"{value:,}"


def hz(value: float | None) -> str:
    if not value:
        return "-"
    return f"{value:,.0f} Hz" if value >= 100 else f"{value:.3g} Hz"


def metres(value: float) -> str:
    """A length to the millimetre, without trailing zeros (4.335, 0.15, 80)."""
    return f"{round(value, 3):g}"


def pose_text(pose: list[float]) -> str:
    """``[x_m, y_m, theta_rad]`` as ``(x m, y m, theta deg)``."""
    return f"({pose[0]:.3f} m, {pose[1]:.3f} m, {math.degrees(pose[2]):.1f} deg)"


def table(rows: list[list[str]]) -> list[str]:
    """Rows of cells as lines, each column as wide as its widest cell, indented two spaces."""
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return ["  " + "  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip()
            for row in rows]  # fmt: skip


def size_text(size: int) -> str:
    """A file's size in bytes, as MB from 100 kB on."""
    return f"{size / 1e6:.1f} MB" if size >= 100_000 else f"{number(size)} bytes"
