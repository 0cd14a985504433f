"""Writers: the end of the flow, turning a finished map or a log into files."""

from __future__ import annotations

from gridmap_cli.errors import GridmapError


def check_metadata_lines(metadata: dict[str, str]) -> None:
    """Refuse metadata that cannot be written as ``# key: value`` header lines."""
    for key, value in metadata.items():
        if not key or ":" in key or any(c in key + value for c in "\r\n"):
            raise GridmapError(f"metadata {key!r}: {value!r} cannot be a '# key: value' line")
