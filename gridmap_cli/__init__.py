"""gridmap: occupancy-grid maps from robot logs of range readings and wheel odometry.

The packages are the stages of the flow (README, "Architecture"): readers -> poses -> mapping ->
writers, with robot, sim, evaluation, runs, describe and cli beside them. The modules at this
level are the core every stage may import (errors, records, atomic, limits, geometry,
yamlfile, heap, extensions); they import no package but :mod:`gridmap_cli.robot`.
"""

from __future__ import annotations

__version__ = "0.1.0"
