"""The canonical records: chunks of readings cut as build cuts them, however they were read."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from gridmap_cli.mapping.shards import batch_bounds
from gridmap_cli.records import RangeReadings, cut_chunks


@given(
    st.lists(st.integers(1, 5), min_size=0, max_size=60),  # readings per stamp
    st.integers(1, 12),  # chunk size
    st.data(),
)
def test_chunks_of_blocks_are_batch_bounds_of_the_whole(
    per_stamp: list[int], size: int, data: st.DataObject
) -> None:
    stamps = np.repeat(np.arange(len(per_stamp), dtype=np.int64) * 7, per_stamp)
    index = np.arange(len(stamps), dtype=np.float64)  # each reading names its place
    whole = RangeReadings(stamps, np.zeros(len(stamps), np.int32), index)
    # blocks of whole stamps, cut anywhere between stamps
    ends = np.cumsum(per_stamp).tolist()
    cuts = sorted(set(data.draw(st.lists(st.sampled_from(ends or [0]), max_size=8))))
    bounds = [0, *cuts, len(stamps)]
    blocks = [whole.part(slice(a, b)) for a, b in itertools.pairwise(bounds)]
    got = [(int(c.range_m[0]), len(c)) for c in cut_chunks(blocks, size)]
    want = [(a, b - a) for a, b in batch_bounds(stamps, size)]
    assert got == want
