"""JSON messages decoded per second by each way of reading gridmap's JSON MCAP channels.

``python bench/bench_json.py LOG.mcap`` (``make bench`` runs it on its JSON MCAP, on one core):
the raw messages of every chunk the bulk reader hands to
:func:`gridmap_cli.readers.ros.mcap.json_bulk.decode` are gathered once, then each way turns
them into the same columns, best of three:

- msgspec: the typed decoder the reader uses;
- json: the standard library's decoder, the reader's way for what msgspec refuses (NaN);
- orjson, where it is installed (``pip install orjson``; not a dependency): each message to a
  dict, then the same checks and columns as the json way.

Every way is checked to give the same columns as the reader, to the bit, before it is timed.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from gridmap_cli.readers.ros.bulk import Columns, Raw
from gridmap_cli.readers.ros.mcap import json_bulk
from gridmap_cli.readers.ros.mcap.log import McapSource

TOPICS = ["/sensors", "/odom", "/ground_truth", "/range"]


def gathered(path: Path) -> list[tuple[str, Raw]]:
    """Every (type, raw messages) the bulk reader decodes, in its order."""
    seen: list[tuple[str, Raw]] = []
    decode = json_bulk.decode

    def keep(type_name: str, raw: Raw) -> Columns:
        seen.append((type_name, raw))
        return decode(type_name, raw)

    json_bulk.decode = keep  # type: ignore[assignment]
    try:
        McapSource(path).bulk(TOPICS)
    finally:
        json_bulk.decode = decode  # type: ignore[assignment]
    return seen


def from_dicts(type_name: str, raw: Raw, msgs: list[dict[str, Any]]) -> Columns:
    build = json_bulk._pose2d if type_name == "gridmap.Pose2D" else json_bulk._reading
    return build(raw, msgs)


def with_msgspec(type_name: str, raw: Raw) -> Columns | None:
    return json_bulk._typed(type_name, raw)


def with_json(type_name: str, raw: Raw) -> Columns:
    return from_dicts(type_name, raw, json_bulk._parse(raw))


def orjson_way() -> Callable[[str, Raw], Columns] | None:
    try:
        import orjson  # type: ignore[import-not-found, unused-ignore]
    except ImportError:
        return None

    def with_orjson(type_name: str, raw: Raw) -> Columns:
        data = raw.buf.tobytes()
        ends = (raw.offset + raw.length).tolist()
        texts = map(data.__getitem__, map(slice, raw.offset.tolist(), ends))
        return from_dicts(type_name, raw, list(map(orjson.loads, texts)))

    return with_orjson


def same(a: Columns | None, b: Columns) -> bool:
    if a is None or a.names != b.names or sorted(a.arrays) != sorted(b.arrays):
        return False
    return all(a.arrays[k].tobytes() == b.arrays[k].tobytes() for k in b.arrays)


def main() -> None:
    chunks = gathered(Path(sys.argv[1]))
    count = sum(len(raw.offset) for _, raw in chunks)
    want = [json_bulk.decode(t, raw) for t, raw in chunks]
    ways: list[tuple[str, Callable[[str, Raw], Columns | None] | None]] = [
        ("msgspec (the reader's)", with_msgspec),
        ("json (standard library)", with_json),
        ("orjson", orjson_way()),
    ]
    print(f"JSON messages decoded per second, {count:,d} messages in {len(chunks)} pieces:")
    for name, way in ways:
        if way is None:
            print(f"  {name:24} skipped (not installed here)")
            continue
        if not all(same(way(t, raw), w) for (t, raw), w in zip(chunks, want, strict=True)):
            sys.exit(f"bench: {name} gives other columns than the reader")
        best = np.inf
        for _ in range(3):
            start = time.perf_counter()
            for t, raw in chunks:
                way(t, raw)
            best = min(best, time.perf_counter() - start)
        print(f"  {name:24} {count / best:12,.0f} messages/s  ({best:.3f} s)")


if __name__ == "__main__":
    main()
