"""What a robot is to gridmap: its range sensors and where each is mounted on the base.

Plain frozen dataclasses and the expansion of a laser into its beams; no file is read here (the
loaders in :mod:`gridmap_cli.robot` and :mod:`gridmap_cli.robot.aria_params` read them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from gridmap_cli.errors import UsageError

SENSOR_KINDS = ("sonar", "laser")


@dataclass(frozen=True)
class RangeSensor:
    """One range sensor: its name, mounting pose in the base frame and beam.

    ``x_m``, ``y_m``: position in the robot base frame (x forward, y left), metres.
    ``yaw_rad``: direction of the beam axis in the base frame, radians, counter-clockwise.
    ``beam_width_rad``: full opening angle of the beam (0 for a ray-like sensor).
    ``min_range_m``, ``max_range_m``: readings below the minimum are discarded; readings at or
    beyond the maximum mean "no echo".
    """

    name: str
    x_m: float
    y_m: float
    yaw_rad: float
    beam_width_rad: float
    min_range_m: float
    max_range_m: float
    kind: str = "sonar"


@dataclass(frozen=True)
class SensorMount:
    """Where a laser sits on the base, without its beams: a ROS recording's LaserScan messages
    carry the beam angles, count and range limits themselves, so a robot file (or
    ``--laser-mount``) need give only this. ``name`` is the laser's frame; empty for the
    mounting of whichever laser is the recording's only one without a mounting."""

    name: str
    x_m: float
    y_m: float
    yaw_rad: float
    #: mounted upside down (under a deck): its beams sweep the base frame the other way round
    upside_down: bool = False


@dataclass(frozen=True)
class RobotDescription:
    """A named robot, its range sensors in a fixed order, and the lasers it gives only the
    mounting of (``mounts``: their beams come from the recording)."""

    name: str
    sensors: tuple[RangeSensor, ...]
    mounts: tuple[SensorMount, ...] = ()

    def names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.sensors)

    def by_name(self) -> dict[str, RangeSensor]:
        return {s.name: s for s in self.sensors}

    def lasers(self) -> dict[str, list[str]]:
        """Each laser's name and its beams' names in beam order (``laser1``: ``laser1_0``...),
        as :func:`laser_beams` names them."""
        beams: dict[str, list[tuple[int, str]]] = {}
        for s in self.sensors:
            stem, _, index = s.name.rpartition("_")
            if s.kind == "laser" and stem and index.isdigit():
                beams.setdefault(stem, []).append((int(index), s.name))
        return {stem: [n for _, n in sorted(b)] for stem, b in beams.items()}


def parse_mount(text: str, flag: str = "--laser-mount") -> tuple[float, float, float]:
    """``X,Y,YAW_DEG`` (metres, degrees) -> (x_m, y_m, yaw_rad); :class:`UsageError` else."""
    try:
        x, y, yaw = (float(p) for p in text.split(","))
    except ValueError:
        raise UsageError(
            f"{flag} {text!r}: expected X,Y,YAW_DEG (metres, degrees, the laser's pose on the "
            "robot's base frame), e.g. 0.2,0,0"
        ) from None
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise UsageError(f"{flag} {text!r}: not finite")
    return x, y, math.radians(yaw)


def laser_beams(
    name: str,
    x_m: float,
    y_m: float,
    yaw_rad: float,
    first_deg: float,
    last_deg: float,
    samples: int,
    min_range_m: float,
    max_range_m: float,
) -> list[RangeSensor]:
    """One ray sensor per beam of a scanning laser, ``<name>_0`` .. ``<name>_<samples-1>``:
    beam i points ``first_deg + i * (last_deg - first_deg) / (samples - 1)`` degrees from the
    laser's axis ``yaw_rad``.

    Robot descriptions and ARIA logs both describe a laser this way; computing its beams in one
    place gives the same laser the same beam directions to the bit, whichever file described it.
    """
    step = (last_deg - first_deg) / (samples - 1) if samples > 1 else 0.0
    return [
        RangeSensor(f"{name}_{i}", x_m, y_m, yaw_rad + math.radians(first_deg + i * step), 0.0,
                    min_range_m, max_range_m, "laser")
        for i in range(samples)
    ]  # fmt: skip
