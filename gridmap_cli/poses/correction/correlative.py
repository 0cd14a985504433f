"""Correlative search: the best pose of a point set on a likelihood grid, by branch and bound.

Where a loop closure's starting guess may be metres and degrees off, GICP (which follows the
nearest correspondences) lands in the wrong place or nowhere. The correlative search (Olson 2009;
Hess et al. 2016, Cartographer's loop closure) scores every pose of a window instead: the target
points are rasterised on a grid whose cells hold ``exp(-d^2 / 2 sigma^2)`` of the distance ``d``
to the nearest target point, and a pose's score is the mean of that over the source points moved
by it (1: every point on a target point; 0: none near one).

The window (``±window_m`` in x and y, ``±window_rad`` in heading) is searched exactly, but fast:
for each heading the translations form a tree; a node covering ``2^L`` by ``2^L`` cells is
bounded by the score on a grid whose cells hold the maximum of the ``2^L`` by ``2^L`` cells above
and to the right of them, so a whole subtree whose bound is below the best score found is never
visited (branch and bound). The answer is the best pose on the grid (to one cell and one heading
step); GICP refines it.
"""

from __future__ import annotations

import itertools
import math
import mmap
from dataclasses import dataclass
from functools import cache

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from gridmap_cli.extensions import optional

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class SearchResult:
    """The best pose of the source in the target's frame (m, m, rad) and its score in [0, 1]."""

    x_m: float
    y_m: float
    theta_rad: float
    score: float


class LikelihoodGrid:
    """The likelihood grid of target points (K, 2) and its max-pooled levels.

    ``resolution_m``: cell size; ``sigma_m``: width of each point's likelihood; ``levels``:
    number of pooled levels above the grid (the coarsest covers ``2^levels`` cells a side);
    ``reach_m``: the largest search window the grid will serve (its zero border is that wide,
    so a point off the grid, moved by any offset of the window, still reads zero).
    """

    def __init__(
        self,
        points: FloatArray,
        resolution_m: float,
        sigma_m: float,
        levels: int,
        reach_m: float,
    ) -> None:
        self.resolution_m = resolution_m
        self.levels = levels
        pad = 2 * (2**levels + 2 + math.ceil(reach_m / resolution_m))
        self.pad = pad
        low = points.min(axis=0) - pad * resolution_m
        high = points.max(axis=0) + pad * resolution_m
        shape = np.ceil((high - low) / resolution_m).astype(int) + 1
        self.origin = low
        cells = np.floor((points - low) / resolution_m).astype(int)
        self.shape = (int(shape[0]), int(shape[1]))
        grids = _pooled_levels(cells, self.shape, pad, resolution_m, sigma_m, levels)
        self.flat = [g.ravel() for g in grids]

    def cells(self, points: FloatArray) -> npt.NDArray[np.intp]:
        """Flat fine cell index (K,) of points (K, 2) in the target's frame; points off the
        grid are put on its zero border."""
        c = np.floor((points - self.origin) / self.resolution_m).astype(np.intp)
        u = np.clip(c[:, 0], self.pad // 2, self.shape[0] - 1 - self.pad // 2)
        v = np.clip(c[:, 1], self.pad // 2, self.shape[1] - 1 - self.pad // 2)
        return np.asarray(u * self.shape[1] + v, dtype=np.intp)

    def offsets(self, cells_uv: npt.NDArray[np.intp]) -> npt.NDArray[np.intp]:
        """Flat index offsets (M,) of cell offsets (M, 2)."""
        return np.asarray(cells_uv[:, 0] * self.shape[1] + cells_uv[:, 1], dtype=np.intp)

    def score(
        self, level: int, cells: npt.NDArray[np.intp], offsets: npt.NDArray[np.intp]
    ) -> FloatArray:
        """Mean over the points' cells (K,) moved by each of ``offsets`` (M,): shape (M,)."""
        g = self.flat[level]
        return np.asarray(g[cells[None, :] + offsets[:, None]].sum(axis=1) / len(cells))


def _pooled_levels(
    cells: npt.NDArray[np.int_],
    shape: tuple[int, int],
    pad: int,
    resolution_m: float,
    sigma_m: float,
    levels: int,
) -> list[npt.NDArray[np.float32]]:
    """The likelihood grid of the hit ``cells`` (K, 2) and its ``levels`` max-pooled copies,
    each of ``shape``, zero in the ``pad`` cells along every edge.

    Only the box that can hold a non-zero value is computed: the likelihood is zeroed within
    ``pad`` of the edges, and a pooled cell reaches ``2^levels - 1`` cells up and right of it.
    The distance to the nearest hit is exact on any box that holds every hit, so the values are
    those of the whole grid, for a fraction of its area.
    """
    lo = max(0, pad - 2**levels)
    hi = (shape[0] - pad, shape[1] - pad)
    # the distance transform's box: the interior and every hit (a hit may round onto the edge)
    r0 = min(lo, int(cells[:, 0].min()))
    c0 = min(lo, int(cells[:, 1].min()))
    r1 = max(hi[0], int(cells[:, 0].max()) + 1)
    c1 = max(hi[1], int(cells[:, 1].max()) + 1)
    hit = np.zeros((r1 - r0, c1 - c0), dtype=bool)
    hit[cells[:, 0] - r0, cells[:, 1] - c0] = True
    dist = ndimage.distance_transform_edt(~hit) * resolution_m
    near = np.exp(-0.5 * (dist / sigma_m) ** 2).astype(np.float32)
    # the pooled box: [lo, hi) in both axes, zero outside the interior [pad, hi); each level
    # is written straight into its grid's box, from the level below's
    grids = _zero_grids(levels + 1, shape)
    boxes = [g[lo : hi[0], lo : hi[1]] for g in grids]
    boxes[0][pad - lo :, pad - lo :] = near[pad - r0 : hi[0] - r0, pad - c0 : hi[1] - c0]
    rows = np.empty_like(boxes[0])
    for level in range(levels):
        g, up, h = boxes[level], boxes[level + 1], 2**level
        np.maximum(g[:-h, :], g[h:, :], out=rows[:-h, :])
        rows[-h:, :] = g[-h:, :]
        np.maximum(rows[:, :-h], rows[:, h:], out=up[:, :-h])
        up[:, -h:] = rows[:, -h:]
    return grids


def _zero_grids(count: int, shape: tuple[int, int]) -> list[npt.NDArray[np.float32]]:
    """``count`` zeroed float32 grids of ``shape`` on anonymous pages of their own.

    Most of a grid is its zero border, which a search reads only next to the target. Fresh
    pages read as zero unwritten and are backed only once touched, so the border costs next to
    nothing; a zeroed block from the C heap is written in full first, and the heap keeps it
    after the grid is freed. The pages go back to the system with the last grid's reference.
    """
    size = shape[0] * shape[1]
    pages = mmap.mmap(-1, max(1, count * size * 4))
    flat = np.frombuffer(pages, dtype=np.float32, count=count * size)
    return [flat[k * size : (k + 1) * size].reshape(shape) for k in range(count)]


def search(
    grid: LikelihoodGrid,
    source: FloatArray,
    guess: tuple[float, float, float],
    window_m: float,
    window_rad: float,
    step_rad: float,
    min_score: float,
) -> SearchResult | None:
    """The best pose of ``source`` (K, 2, its own frame) on ``grid`` within the window around
    ``guess`` (source in the target's frame), or None when no pose scores ``min_score``."""
    res = grid.resolution_m
    reach = max(1, math.ceil(window_m / res))
    size = 2**grid.levels
    # the coarsest nodes tile [-reach, reach] in both axes
    starts = np.arange(-reach, reach + 1, size)
    ox, oy = np.meshgrid(starts, starts, indexing="ij")
    tiles = np.column_stack([ox.ravel(), oy.ravel()]).astype(np.intp)
    n_turns = max(0, math.floor(window_rad / step_rad))
    thetas = [guess[2] + k * step_rad for k in range(-n_turns, n_turns + 1)]
    cells_by_turn: list[npt.NDArray[np.intp]] = []
    for theta in thetas:
        c, s = math.cos(theta), math.sin(theta)
        moved = np.column_stack(
            [
                guess[0] + c * source[:, 0] - s * source[:, 1],
                guess[1] + s * source[:, 0] + c * source[:, 1],
            ]
        )
        cells_by_turn.append(grid.cells(moved))
    compiled = optional("gridmap_cli.poses.correction._cbranch")
    # the compiled walk reads the cells as 32-bit indices
    if compiled is not None and len(source) and grid.flat[0].size < 2**31:
        found = compiled.search(
            grid.flat, grid.shape[1], np.ascontiguousarray(cells_by_turn, dtype=np.int32),
            len(thetas), np.ascontiguousarray(tiles, dtype=np.int64), reach, min_score,
            _argsort_table(),
        )  # fmt: skip
        if found is None:
            return None
        score, t, u, v = found
        return SearchResult(guess[0] + u * res, guess[1] + v * res, thetas[t], score)
    best = _branch_and_bound(grid, cells_by_turn, tiles, reach, min_score)
    if best is None:
        return None
    score, t, (u, v) = best
    return SearchResult(guess[0] + u * res, guess[1] + v * res, thetas[t], score)


def _branch_and_bound(
    grid: LikelihoodGrid,
    cells_by_turn: list[npt.NDArray[np.intp]],
    tiles: npt.NDArray[np.intp],
    reach: int,
    min_score: float,
) -> tuple[float, int, tuple[int, int]] | None:
    """The best (score, heading index, cell offset) above ``min_score``: the roots (``tiles``
    at each heading's cells) by decreasing bound, each searched depth first below it."""
    top = grid.levels
    best_score: float = min_score
    best: tuple[float, int, tuple[int, int]] | None = None
    roots: list[tuple[float, int, npt.NDArray[np.intp]]] = []
    for t, cells in enumerate(cells_by_turn):
        bounds = grid.score(top, cells, grid.offsets(tiles))
        roots.extend((float(b), t, tiles[m]) for m, b in enumerate(bounds))
    roots.sort(key=lambda r: -r[0])
    for bound, t, offset in roots:
        if bound <= best_score:
            break
        found = _descend(grid, cells_by_turn[t], offset, top, best_score, reach)
        if found is not None:
            best_score = found[0]
            best = (found[0], t, found[1])
    return best


@cache
def _argsort_table() -> bytes:
    """numpy's argsort order of up to 4 float32 scores, for the compiled branch and bound: 4
    indices for each count (1 to 4) and code (the scores' dense ranks as base-4 digits). The
    order of tied scores is the sort's own, so it is read from numpy rather than assumed."""
    table = bytearray(4 * 256 * 4)
    for n in range(1, 5):
        for ranks in itertools.product(range(n), repeat=n):
            if set(ranks) != set(range(max(ranks) + 1)):
                continue  # not dense
            code = 0
            for r in ranks:
                code = code * 4 + r
            order = np.argsort(np.array(ranks, dtype=np.float32))
            at = ((n - 1) * 256 + code) * 4
            table[at : at + n] = bytes(int(i) for i in order)
    return bytes(table)


def _descend(
    grid: LikelihoodGrid,
    cells: npt.NDArray[np.intp],
    offset: npt.NDArray[np.intp],
    level: int,
    floor: float,
    reach: int,
) -> tuple[float, tuple[int, int]] | None:
    """Depth-first branch and bound below one node: the best (score, offset) above ``floor``."""
    best: tuple[float, tuple[int, int]] | None = None
    stack: list[tuple[float, npt.NDArray[np.intp], int]] = [(math.inf, offset, level)]
    while stack:
        bound, node, lv = stack.pop()
        if bound <= floor:
            continue
        h = 2 ** (lv - 1)
        kids = node[None, :] + np.array([[0, 0], [h, 0], [0, h], [h, h]], dtype=np.intp)
        inside = (np.abs(kids) <= reach).all(axis=1)
        kids = kids[inside]
        if len(kids) == 0:
            continue
        scores = grid.score(lv - 1, cells, grid.offsets(kids))
        order = np.argsort(scores)  # ascending: the best is pushed last and popped first
        for m in order:
            if scores[m] <= floor:
                continue
            if lv - 1 == 0:
                floor = float(scores[m])
                best = (floor, (int(kids[m, 0]), int(kids[m, 1])))
            else:
                stack.append((float(scores[m]), kids[m], lv - 1))
    return best
