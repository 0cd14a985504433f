"""``gridmap inspect``: what a log holds and what ``build`` would make of it.

:func:`describe_log` returns plain data (the ``--json`` output); :func:`render_text` turns it
into the text a person reads. One module per subject, each with its part of the data and its
section of the text: :mod:`.recording` (a ROS recording's files, channels, TF and frames),
:mod:`.selection` (``--sensors``, ``--start``, ``--end``), :mod:`.tracks` (the odometry and
reference tracks and the range readings: counts, time spans, rates), :mod:`.sensors` (each
sensor's mounting and its source, its lasers) and :mod:`.verdict` (what build would use and
the error it would stop at: build's own checks, not a parallel set of rules); :mod:`.report`
puts them together, :mod:`.text` holds the formatting they share.

May import: the core, :mod:`gridmap_cli.robot`, :mod:`gridmap_cli.readers`,
:mod:`gridmap_cli.poses` and :mod:`gridmap_cli.mapping` (build's plan and selection). Nothing
here prints or writes a file; only :mod:`gridmap_cli.cli` imports this package.
"""

from __future__ import annotations

from gridmap_cli.describe.report import describe_log, render_text

__all__ = ["describe_log", "render_text"]
