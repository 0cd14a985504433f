"""The oracle the fast expected map (:mod:`gridmap_cli.mapping.expected`) is measured against:
each sampled track's full standard build, probabilities averaged (tests and
``bench/expected_map.py``)."""

from __future__ import annotations

import dataclasses

import numpy as np

from gridmap_cli.mapping.grid import LogOddsAccumulator, OccupancyMap
from gridmap_cli.mapping.plan import BuildPlan
from gridmap_cli.mapping.shards import accumulate_log_odds
from gridmap_cli.poses.odometry_error import travelled
from gridmap_cli.records import PoseTrack


def exact(
    plan: BuildPlan,
    tracks: list[PoseTrack],
    clamp_p: tuple[float, float],
    batch_size: int,
) -> OccupancyMap:
    """The oracle the fast map is measured against: the full standard build of every track in
    ``tracks`` (synchronised again, on the map's cells), probabilities averaged. ``plan``'s
    models must map every reading (no heading-spread cut)."""
    shape = (plan.spec.height, plan.spec.width)
    total, seen = np.zeros(shape), np.zeros(shape, dtype=bool)
    for track in tracks:
        moved = dataclasses.replace(plan.log, poses=track)
        part = dataclasses.replace(plan, log=moved, travelled=travelled(track))
        grid = LogOddsAccumulator(plan.spec)
        accumulate_log_odds(part, grid, batch_size, 1)
        prob = grid.occupancy_map(clamp_p).prob
        known = ~np.isnan(prob)
        seen |= known
        total += np.where(known, prob, 0.5)
    return OccupancyMap(plan.spec, np.where(seen, total / len(tracks), np.nan))
