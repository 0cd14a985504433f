"""Small YAML files: reading a top-level mapping with each key's line, numbers in and out.

The map YAML and the odometry-error file share these, so both read '5e-2' as a number and write
floats that read back exactly.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import yaml

from gridmap_cli.errors import InputFileError
from gridmap_cli.limits import read_settings_text


def read_yaml_mapping(
    path: Path, kind: str, not_mapping: str
) -> tuple[dict[Any, Any], dict[str, int]]:
    """The mapping in ``path`` and the 1-based line of each top-level key's value.

    ``kind`` names the file in the error for a directory ("a map YAML"); ``not_mapping`` is the
    error when the document is not a mapping. Raises :class:`InputFileError` for a missing,
    unreadable or non-UTF-8 file and invalid YAML (with its line).
    """
    try:
        text = read_settings_text(path, kind)
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
        line, problem = yaml_problem(exc)
        raise InputFileError(path, problem, line=line) from exc
    if not isinstance(doc, dict):
        raise InputFileError(path, not_mapping)
    lines: dict[str, int] = {}
    if isinstance(root, yaml.MappingNode):
        for key_node, value_node in root.value:
            if isinstance(key_node.value, str):
                lines[key_node.value] = value_node.start_mark.line + 1
    return doc, lines


def yaml_problem(exc: yaml.YAMLError) -> tuple[int | None, str]:
    """The 1-based line and a one-line description of a YAML syntax error.

    ``str(exc)`` is the parser's several-line block with a caret under the place; errors are
    one line, so the place goes in the ``path:line`` prefix and the column in the text.
    """
    mark = getattr(exc, "problem_mark", None)
    line = mark.line + 1 if mark is not None else None
    problem = getattr(exc, "problem", None) or str(exc)
    context = getattr(exc, "context", None)
    text = f"{context}: {problem}" if context else problem
    column = f" (column {mark.column + 1})" if mark is not None else ""
    return line, " ".join(f"not valid YAML: {text}{column}".split())


def number(value: object) -> float | None:
    """A YAML value as a float, or None if it is not a number.

    Strings that parse as numbers count: PyYAML reads '5e-2' (no '.') as a string, while the
    yaml-cpp loaders read it as a number. Booleans are not numbers.
    """
    if isinstance(value, bool):
        return None
    if isinstance(value, int | float):
        return float(value)
    if isinstance(value, str):
        try:
            return float(value.strip())
        except ValueError:
            return None
    return None


def format_float(value: float) -> str:
    """Shortest text that reads back as exactly ``value`` in yaml-cpp and in PyYAML.

    ``repr`` round-trips, but PyYAML's YAML 1.1 resolver wants a '.' in a float ('1e-05' would
    load as a string), so an exponent form without one gets '.0' before the 'e'. Raises
    ``ValueError`` for NaN and infinities, which gridmap's YAML files never hold.
    """
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"a gridmap YAML file cannot hold the non-finite number {value}")
    text = repr(value)
    mantissa, e, exponent = text.partition("e")
    if e and "." not in mantissa:
        text = f"{mantissa}.0e{exponent}"
    return text
