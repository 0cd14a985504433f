"""Reading a small YAML file whose top level is a mapping, keeping each key's line for errors."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from gridmap_cli.errors import InputFileError


def read_yaml_mapping(
    path: Path, kind: str, not_mapping: str
) -> tuple[dict[Any, Any], dict[str, int]]:
    """The mapping in ``path`` and the 1-based line of each top-level key's value.

    ``kind`` names the file in the error for a directory ("a map YAML"); ``not_mapping`` is the
    error when the document is not a mapping. Raises :class:`InputFileError` for a missing,
    unreadable or non-UTF-8 file and invalid YAML (with its line).
    """
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputFileError(path, "no such file") from None
    except IsADirectoryError:
        raise InputFileError(path, f"is a directory, not {kind}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputFileError(path, f"cannot read: {exc}") from exc
    try:
        doc = yaml.safe_load(text)
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        problem = getattr(exc, "problem", None) or str(exc)
        raise InputFileError(path, f"not valid YAML: {problem}", line=line) from exc
    if not isinstance(doc, dict):
        raise InputFileError(path, not_mapping)
    lines: dict[str, int] = {}
    if isinstance(root, yaml.MappingNode):
        for key_node, value_node in root.value:
            if isinstance(key_node.value, str):
                lines[key_node.value] = value_node.start_mark.line + 1
    return doc, lines
