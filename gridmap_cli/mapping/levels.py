"""The coarse grids of the fast expected map (:mod:`gridmap_cli.mapping.expected`): a level's
cells ``2 ** level`` times the map's, sharing its origin, and the way a level's log-odds and
seen cells come back onto the map's cells (linearly between the coarse cells' centres)."""

from __future__ import annotations

from typing import TypeVar

import numpy as np
import numpy.typing as npt

from gridmap_cli.mapping.grid import GridSpec

T = TypeVar("T", bound=np.generic)
F64 = npt.NDArray[np.float64]


def level_spec(spec: GridSpec, level: int) -> GridSpec:
    """The grid of cells ``2 ** level`` times the map's, sharing its origin and covering it."""
    f = 1 << level
    return GridSpec(
        spec.origin_x_m, spec.origin_y_m, spec.resolution_m * f, -(-spec.width // f),
        -(-spec.height // f),
    )  # fmt: skip


def upsample(values: npt.NDArray[T], spec: GridSpec, level: int) -> npt.NDArray[T]:
    """A level's cells onto the map's: each map cell takes its coarse cell's value."""
    if level == 0:
        return values
    f = 1 << level
    return np.repeat(np.repeat(values, f, axis=0), f, axis=1)[: spec.height, : spec.width]


def known_cells(
    spec: GridSpec, observed: dict[int, npt.NDArray[np.bool_]]
) -> npt.NDArray[np.bool_]:
    """The map's cells some sample's reading touched, from each level's cells some sample's
    reading touched (level -1, cast once, is on the map's cells). A coarse level's
    cells that were seen are spread onto the map's cells as its log-odds are (linearly,
    :func:`finer`), and a map cell counts as seen where that reaches a half: the edge of what
    is known is drawn at the map's resolution, where copying the coarse cells would draw it in
    blocks of up to 16 cells, and it stays within a coarse cell of them."""
    seen = np.zeros((spec.height, spec.width), dtype=bool)
    for level, counts in observed.items():
        if level <= 0:
            seen |= counts
            continue
        share = counts.astype(np.float64)
        for below in range(level - 1, -1, -1):
            share = finer(share, level_spec(spec, below))
        seen |= share >= 0.5
    return seen


def finer(values: F64, fine: GridSpec) -> F64:
    """A level's log-odds onto the next finer level's cells, linear between the coarse cells'
    centres (a finer cell's centre lies a quarter of a coarse cell from its coarse cell's
    centre). Copying each coarse cell's value drew the coarse cells as blocks and scored
    worse (docs/sensor-model.md)."""
    out = _halves(_halves(values, 0), 1)
    return out[: fine.height, : fine.width]


def _halves(values: F64, axis: int) -> F64:
    """Each cell along ``axis`` split in two, 3/4 of its own value and 1/4 of the neighbour's
    on that side (its own at the grid's edge)."""
    v = np.moveaxis(values, axis, 0)
    out = np.empty((2 * v.shape[0], *v.shape[1:]))
    quarter = 0.25 * v
    for half, near, own in ((out[0::2], slice(None, -1), slice(1, None)),
                            (out[1::2], slice(1, None), slice(None, -1))):  # fmt: skip
        np.multiply(v, 0.75, out=half)
        half[own] += quarter[near]  # the neighbour's quarter; at the edge its own
        edge = 0 if own.start else -1
        half[edge] += quarter[edge]
    return np.moveaxis(out, 0, axis)
