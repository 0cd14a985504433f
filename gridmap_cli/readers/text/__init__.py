"""Text log readers: CSV (:mod:`.csv_log`, long logs streamed by :mod:`.csv_stream`), ARIA
``.2d`` logs (:mod:`.aria_log`), CARMEN logs (:mod:`.carmen_log`, their corrected and raw tracks
in :mod:`.carmen_tracks`, the beam layout its PARAM lines give in
:mod:`.carmen_layout`), gzip (:mod:`.compressed`) and the line source they share
(:mod:`.source`).

Each turns its format into the canonical :class:`~gridmap_cli.records.RangeLog`.
May import: the core (errors, limits, records, geometry) and :mod:`gridmap_cli.robot`.
"""
