"""Builds: :mod:`.build` is the one build function (a request in, the map and its track out)
and :mod:`.settings` the map options as one value; many builds at once: :mod:`.batch` maps a
folder of logs, :mod:`.fuse` maps several recordings into one map, :mod:`.executors` runs
either on local processes or a Dask cluster; :mod:`.content` keys a log by its content.

May import: everything below the CLI (readers, poses, mapping, evaluation, writers, the core).
"""
