"""The part of a log ``--sensors``, ``--start`` and ``--end`` select, and the notes selecting
left (CSV columns that are no sensor).

:func:`selection_part` is the ``selection`` part of the description, :func:`selection_lines`
its text (the notes as warnings first).
"""

from __future__ import annotations

from typing import Any

from gridmap_cli.mapping.selection import Selected, Selection, names_text
from gridmap_cli.records import stamp_text


def selection_part(selection: Selection, selected: Selected) -> dict[str, Any]:
    """The flags as given, the window as stamps, and the sensors kept of those in the log."""
    names = selected.log.sensor_names
    return {
        "sensors": list(selection.sensors),
        "start": selection.start.text if selection.start is not None else None,
        "end": selection.end.text if selection.end is not None else None,
        "start_ns": selected.start_ns,
        "end_ns": selected.end_ns,
        "sensors_selected": len(names),
        "sensors_in_log": selected.sensors_before,
        "sensor_names": names_text(names),
    }


def selection_lines(sel: dict[str, Any] | None, notes: list[str]) -> list[str]:
    """The notes as warnings, then the selection section (none without a selection)."""
    lines = [f"Warning: {note}" for note in notes]
    if sel is None:
        return lines
    flags = [f"--sensors '{p}'" for p in sel["sensors"]]
    flags += [f"--{k} {sel[k]}" for k in ("start", "end") if sel[k] is not None]
    lines += ["", f"Selection ({' '.join(flags)}): the rest of this description is of it"]
    lines.append(
        f"  sensors   {sel['sensors_selected']} of {sel['sensors_in_log']}: "
        f"{sel['sensor_names'] or 'none'}"
    )
    if sel["start_ns"] is not None or sel["end_ns"] is not None:
        lo = stamp_text(sel["start_ns"]) if sel["start_ns"] is not None else "the start"
        hi = stamp_text(sel["end_ns"]) if sel["end_ns"] is not None else "the end"
        lines.append(f"  readings  from {lo} to {hi} (not including it)")
    return lines
