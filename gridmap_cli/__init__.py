"""gridmap: occupancy-grid maps from robot logs of range readings and wheel odometry."""

from __future__ import annotations

__version__ = "0.1.0"
