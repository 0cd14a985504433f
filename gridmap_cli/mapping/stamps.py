"""Stamps a time window cannot trust: a log whose stamps never advance, or jump by years.

Such logs still map (every reading has its pose); what they cannot honour is ``--start``/``--end``,
and ``inspect``'s rates and span mean nothing. :func:`stamp_problem` says what is wrong, for a
warning; nothing here prints.
"""

from __future__ import annotations

import numpy as np

from gridmap_cli.records import RangeLog, stamp_text, stamps_advance

#: A gap between consecutive stamps longer than this is a jump no recording makes (365 days).
MAX_GAP_NS = 365 * 86_400 * 1_000_000_000


def stamp_problem(log: RangeLog) -> str | None:
    """What is wrong with the stamps of ``log`` (poses and readings together), or None.

    Streamed readings (:attr:`RangeLog.stream`) count by each sensor's first and last stamp,
    which their reader's checking pass found: a jump among them shows as it does held."""
    parts = [t for t in (log.poses.stamp_ns, log.readings.stamp_ns) if len(t)]
    n_readings = len(log.readings)
    if log.stream is not None:
        kept = (log.stream.index >= 0) & (log.stream.counts > 0)
        parts += [t[kept] for t in (log.stream.first_ns, log.stream.last_ns) if kept.any()]
        n_readings += len(log.stream)
    if not parts:
        return None
    # readings share their scan's stamp: drop repeats first (linear) so the sort is per scan
    stamps = np.sort(np.concatenate([t[np.r_[True, t[1:] != t[:-1]]] for t in parts]))
    span_ns = int(stamps[-1] - stamps[0])
    # records: poses, or scans when there is no pose track (a scan's readings share a stamp)
    records = max(len(log.poses), n_readings // max(len(log.sensor_names), 1))
    if not stamps_advance(int(stamps[0]), int(stamps[-1]), records):
        return (
            f"the stamps do not advance ({records:,} records within {span_ns / 1e9:g} s from "
            f"{stamp_text(int(stamps[0]))}): rates and time windows mean nothing"
        )
    gaps = np.diff(stamps)
    i = int(np.argmax(gaps))
    if int(gaps[i]) > MAX_GAP_NS:
        years = int(gaps[i]) / (365.25 * 86_400e9)
        return (
            f"the stamps jump by {years:,.0f} years (from {stamp_text(int(stamps[i]))} to "
            f"{stamp_text(int(stamps[i + 1]))}): the span and time windows mean nothing"
        )
    return None
