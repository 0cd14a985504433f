"""The beam layout of a CARMEN FLASER/RLASER laser from its PARAM lines and its beam count.

CARMEN's ``laser_<word>_laser_fov`` and ``laser_<word>_laser_resolution`` are meant in degrees,
but real logs write the field of view in radians (``3.14159``). The unit is inferred: a field of
view below a full turn read as degrees (3.14 degrees over 361 beams) is no laser, and the
resolution, if given, must span the beams in the unit that agrees with the field of view.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Below this many degrees, a field of view over many beams is no scanning laser.
MIN_FOV_DEG = 10.0
#: "Many beams": a resolution alone is read as radians only for at least this many (a 5-beam
#: test log at 0.5 deg spans 2 deg and is still meant in degrees).
MANY_BEAMS = 30


@dataclass(frozen=True)
class Layout:
    """Beams from ``start_rad`` every ``step_rad`` (robot frame, counterclockwise)."""

    start_rad: float
    step_rad: float
    read: str  # what the PARAM lines were read as, for ``inspect``; "" when none was given


def layout_from_params(
    fov: float | None, resolution: float | None, count: int, default_step_rad: float
) -> Layout:
    """The layout of ``count`` beams from the fov/resolution PARAM values (either may be None).

    ``default_step_rad`` is CARMEN's guess from the beam count, used when no resolution is given.
    """
    notes: list[str] = []
    fov_rad: float | None = None
    if fov is not None and fov > 0:
        if fov <= 2.0 * math.pi * (1.0 + 1e-3):
            fov_rad = fov
            notes.append(
                f"fov {fov:g} read as radians ({math.degrees(fov):g} deg; "
                f"{fov:g} deg over {count} beams is no laser)"
            )
        else:
            fov_rad = math.radians(fov)
            notes.append(f"fov {fov:g} deg")
    step = default_step_rad
    if resolution is not None and resolution > 0:
        step, note = _resolution(resolution, count, fov_rad)
        notes.append(note)
    if fov_rad is None:
        fov_rad = math.pi
    elif count > 1 and not _spans(step, count, fov_rad):
        notes.append(
            f"{count} beams every {math.degrees(step):g} deg do not span the fov "
            f"{math.degrees(fov_rad):g} deg: the resolution is used"
        )
    return Layout(-fov_rad / 2.0, step, "; ".join(notes))


def _resolution(value: float, count: int, fov_rad: float | None) -> tuple[float, str]:
    """The beam spacing (radians) a resolution PARAM means, and what it was read as."""
    as_deg, as_rad = math.radians(value), value
    if count <= 1:
        return as_deg, f"resolution {value:g} deg"
    if fov_rad is not None:
        # the unit whose span over the beams matches the field of view
        if not _spans(as_deg, count, fov_rad) and _spans(as_rad, count, fov_rad):
            return as_rad, f"resolution {value:g} read as radians ({math.degrees(value):g} deg)"
        return as_deg, f"resolution {value:g} deg"
    if not _plausible(as_deg, count) and _plausible(as_rad, count):
        return as_rad, f"resolution {value:g} read as radians ({math.degrees(value):g} deg)"
    return as_deg, f"resolution {value:g} deg"


def _spans(step_rad: float, count: int, fov_rad: float) -> bool:
    """True if ``count`` beams ``step_rad`` apart cover ``fov_rad`` (end beams in or not)."""
    return abs(step_rad * (count - 1) - fov_rad) <= 1.5 * step_rad


def _plausible(step_rad: float, count: int) -> bool:
    span_deg = math.degrees(step_rad * (count - 1))
    too_narrow = count >= MANY_BEAMS and span_deg < MIN_FOV_DEG
    return not too_narrow and span_deg <= 360.0 + math.degrees(step_rad)
