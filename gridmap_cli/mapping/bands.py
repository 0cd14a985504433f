"""The sampled expected map's running mean over samples, cut into row bands on large maps.

Each sample's standard map is added to a running sum of probabilities (8 bytes a cell), a strip
at a time; the per-sample grid is mapped in row bands when a whole one would break the build's
memory bound. :mod:`gridmap_cli.mapping.pipeline` maps the samples; this module holds the
arithmetic, with no file I/O.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from gridmap_cli.mapping.grid import STRIP_CELLS, GridSpec

#: Bytes a cell the sampled expected map may take on top of its running sum (8 bytes a cell):
#: the per-sample grid (12 bytes a cell) is cut into row bands to stay within it, so that the
#: whole build stays within 12 bytes a cell plus a fixed allowance (README, "Speed").
SAMPLE_GRID_BYTES_PER_CELL = 4
#: Cells of the per-sample grid always allowed in one band (96 MiB at 12 bytes a cell): maps
#: up to about 8 million cells are mapped in one band, each sample's readings in one pass.
SAMPLE_GRID_FREE_CELLS = 8 << 20


def sample_bands(spec: GridSpec, samples: int) -> list[tuple[int, int]]:
    """The row bands ``[row0, row1)`` the sampled expected map maps each sample in: one band
    unless the map is large (:data:`SAMPLE_GRID_BYTES_PER_CELL`). Each band reads the log's
    readings again for every sample, so a band costs a pass over the log per sample; the map is
    the same for any bands (integer sums, each cell in one band)."""
    cells = spec.height * spec.width
    allowed = SAMPLE_GRID_FREE_CELLS + cells * SAMPLE_GRID_BYTES_PER_CELL // 12
    if samples <= 1 or cells <= allowed:
        return [(0, spec.height)]
    n = -(-cells // allowed)
    step = -(-spec.height // n)
    return [(r, min(spec.height, r + step)) for r in range(0, spec.height, step)]


def add_sample(total: npt.NDArray[np.float64], prob: npt.NDArray[np.float64]) -> None:
    """Add one sample's probabilities (NaN where it saw nothing: counts as the prior 0.5) to
    the running sum, strip by strip; a cell stays negated until some sample has seen it. The
    sum's magnitude is the plain sum over the samples in order, as ``total += where(seen, p,
    0.5)`` makes it (to the bit)."""
    step = STRIP_CELLS
    for k in range(0, total.shape[0], step):
        t, p = total[k : k + step], prob[k : k + step]
        known = ~np.isnan(p)
        s = np.abs(t) + np.where(known, p, 0.5)
        total[k : k + step] = np.where((t > 0.0) | known, s, -s)


def mean_in_place(total: npt.NDArray[np.float64], count: int) -> None:
    """The running sum as the mean over ``count`` samples; NaN where no sample saw the cell."""
    step = STRIP_CELLS
    for k in range(0, total.shape[0], step):
        t = total[k : k + step]
        total[k : k + step] = np.where(t > 0.0, t / count, np.nan)
