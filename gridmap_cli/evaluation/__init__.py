"""Map quality against ground truth: :mod:`.evaluate` scores a map against a world or a
reference map, :mod:`.metrics` holds the measures, :mod:`.spread_map` draws the error-aware
spread (and the layer written beside a map), :mod:`.quality` what a log tells of its map without
ground truth (:mod:`.revisits` its track on the places the pose graph found twice),
:mod:`.plot` the figures (matplotlib, the ``plot`` extra), :mod:`.relations` scores a track
against the SLAM benchmark's ground-truth relations.

May import: the core, :mod:`gridmap_cli.robot`, :mod:`gridmap_cli.poses`,
:mod:`gridmap_cli.mapping` and :mod:`gridmap_cli.sim` (a simulated world is a ground truth).
"""
