"""The simulator: synthetic logs of a robot driving through a known world.

One module per part, in the order data flows: :mod:`~gridmap_cli.sim.world` (occupancy grid and
ray casting), :mod:`~gridmap_cli.sim.path` (path files and the true trajectory),
:mod:`~gridmap_cli.sim.odometry` (drifting wheel odometry), :mod:`~gridmap_cli.sim.sonar` (range
readings) and :mod:`~gridmap_cli.sim.simulate` (all of them into one
:class:`~gridmap_cli.records.RangeLog`).

Nothing is re-exported here: ``simulate`` is both a module and its main function, and importing
the function into this package would hide the module.

May import: the core, :mod:`gridmap_cli.robot`, :mod:`gridmap_cli.poses` (the odometry-error
model drives the drift) and :mod:`gridmap_cli.mapping.grid` (a world is a grid).
"""
