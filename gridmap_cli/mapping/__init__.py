"""Mapping: synchronised readings -> sensor models -> grid -> finished map.

:mod:`.selection` picks the sensors and the time window (``--sensors``, ``--start``, ``--end``),
:mod:`.stamps` the stamps such a window cannot trust;
:mod:`.pipeline` plans a build (:mod:`.plan`) and runs it, on one process or several
(:mod:`.shards`); :mod:`.models` hold the sensor models (standard, error-aware, ray) and their
compiled kernels; :mod:`.grid` is the log-odds accumulator and the finished
:class:`~gridmap_cli.mapping.grid.OccupancyMap`; :mod:`.mapfile` loads a written map back.

May import: the core, :mod:`gridmap_cli.robot`, :mod:`gridmap_cli.poses` and the text readers'
stamp helpers. No file is written here (writers do that) and nothing is printed.
"""
