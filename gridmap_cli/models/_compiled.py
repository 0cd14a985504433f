"""numba kernels of the standard sonar cone and the ray model (imported only through
:mod:`gridmap_cli.models.kernels`, which decides when they pay for their start-up).

Each kernel repeats its numpy reference operation for operation, in the same order, so that the
grids are equal bit for bit: the per-reading trigonometry stays in numpy (numba's sin and cos may
differ from numpy's in the last bit), the row and span arithmetic here is plain IEEE +, -, *, /,
sqrt, floor and ceil (no fastmath, so no fused multiply-adds), and evidence goes into a per-batch
difference array in the order ``np.bincount`` adds it (every run's start, then every run's end),
which is then added to the running sums as ``SpanSums.add`` does.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _half_plane(a: float, b: float, dy: float) -> tuple[float, float]:
    if a == 0.0:
        if b * dy >= 0.0:
            return -math.inf, math.inf
        return math.inf, -math.inf
    bound = (-b * dy) / a
    if a > 0.0:
        return bound, math.inf
    return -math.inf, bound


@njit(cache=True, inline="always")
def _span(
    lo_m: float, hi_m: float, dy: float, r: float, sx: float, ox: float, res: float, width: int
) -> tuple[bool, int, int]:
    d2 = r * r - dy * dy
    half = math.sqrt(max(d2, 0.0))
    lo = max(lo_m, -half)
    hi = min(hi_m, half)
    c0f = math.ceil((sx + lo - ox) / res - 0.5)
    c1f = math.floor((sx + hi - ox) / res - 0.5)
    keep = d2 >= 0.0 and r > 0.0 and c0f <= c1f and c1f >= 0 and c0f <= width - 1
    if not keep:
        return False, 0, 0
    return True, int(min(max(c0f, 0.0), width - 1.0)), int(min(max(c1f, 0.0), width - 1.0))


@njit(cache=True)
def sector_batch(
    ox: float,
    oy: float,
    res: float,
    width: int,
    height: int,
    x: np.ndarray,
    y: np.ndarray,
    sin_r: np.ndarray,
    cos_r: np.ndarray,
    sin_l: np.ndarray,
    cos_l: np.ndarray,
    j0: np.ndarray,
    counts: np.ndarray,
    outer_m: np.ndarray,
    outer_value: np.ndarray,
    inner_m: np.ndarray,
    inner_value: np.ndarray,
    value_sums: np.ndarray,
    count_sums: np.ndarray,
) -> int:
    """One batch of nested sectors into the running difference arrays; returns the outer cells.

    One pass over the rows adds every run's start; the ends are kept in order and added after,
    as ``np.bincount`` adds the concatenated starts and ends.
    """
    stride = width + 1
    total = 0
    for m in range(x.shape[0]):
        total += max(counts[m], 0)
    outer_end = np.empty(total, dtype=np.int64)
    inner_end = np.empty(total, dtype=np.int64)
    outer_end_value = np.empty(total)
    inner_end_value = np.empty(total)
    n_outer = 0
    n_inner = 0
    delta_outer = np.zeros(value_sums.shape[0])
    delta_inner = np.zeros(value_sums.shape[0])
    cells = 0
    for m in range(x.shape[0]):
        if counts[m] <= 0:
            continue
        r_out, v_out = outer_m[m], outer_value[m]
        r_in, v_in = inner_m[m], inner_value[m]
        a1, b1 = -sin_r[m], cos_r[m]
        a2, b2 = sin_l[m], -cos_l[m]
        sx = x[m]
        for k in range(counts[m]):
            row = j0[m] + k
            dy = oy + (row + 0.5) * res - y[m]
            lo1, hi1 = _half_plane(a1, b1, dy)
            lo2, hi2 = _half_plane(a2, b2, dy)
            lo, hi = max(lo1, lo2), min(hi1, hi2)
            base = row * stride
            keep, c0, c1 = _span(lo, hi, dy, r_out, sx, ox, res, width)
            if keep:
                count_sums[base + c0] += 1
                count_sums[base + c1 + 1] -= 1
                cells += c1 - c0 + 1
                if v_out != 0.0:
                    delta_outer[base + c0] += v_out
                    outer_end[n_outer] = base + c1 + 1
                    outer_end_value[n_outer] = -v_out
                    n_outer += 1
            keep, c0, c1 = _span(lo, hi, dy, r_in, sx, ox, res, width)
            if keep:
                delta_inner[base + c0] += v_in
                inner_end[n_inner] = base + c1 + 1
                inner_end_value[n_inner] = -v_in
                n_inner += 1
    for k in range(n_outer):
        delta_outer[outer_end[k]] += outer_end_value[k]
    value_sums += delta_outer
    for k in range(n_inner):
        delta_inner[inner_end[k]] += inner_end_value[k]
    value_sums += delta_inner
    return cells


@njit(cache=True)
def ray_batch(
    width: int,
    ra: np.ndarray,
    rb: np.ndarray,
    p_lo: np.ndarray,
    counts: np.ndarray,
    off: np.ndarray,
    slope: np.ndarray,
    ua: np.ndarray,
    ub: np.ndarray,
    clip: bool,
    l_free: float,
    value_sums: np.ndarray,
    count_sums: np.ndarray,
) -> int:
    """One chunk of rays' free runs into the running difference arrays; returns the cells.

    Pass 0: run starts (and counts), pass 1: run ends.
    """
    stride = width + 1
    delta = np.zeros(value_sums.shape[0])
    cells = 0
    for step in range(2):
        for i in range(ra.shape[0]):
            n = counts[i]
            if n <= 0:
                continue
            p_hi = p_lo[i] + n - 1
            for p in range(p_lo[i], p_hi + 1):
                pf = float(p)
                u_in = (pf + off[i]) * slope[i] + ua[i]
                u_out = (pf + 1.0 + off[i]) * slope[i] + ua[i]
                if p == p_lo[i] and p_lo[i] == 0:
                    u_in = ua[i]
                if p == p_hi and ra[i] + p_hi == rb[i]:
                    u_out = ub[i]
                c_in = int(math.floor(u_in))  # noqa: RUF046 (numba: keep the int explicit)
                c_out = int(math.floor(u_out))  # noqa: RUF046
                col0 = min(c_in, c_out)
                col1 = max(c_in, c_out)
                if clip:
                    if col1 < 0 or col0 > width - 1:
                        continue
                    col0 = max(col0, 0)
                    col1 = min(col1, width - 1)
                base = (ra[i] + p) * stride
                if step == 0:
                    count_sums[base + col0] += 1
                    count_sums[base + col1 + 1] -= 1
                    cells += col1 - col0 + 1
                    delta[base + col0] += l_free
                else:
                    delta[base + col1 + 1] += -l_free
    value_sums += delta
    return cells
