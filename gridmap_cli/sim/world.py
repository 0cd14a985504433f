"""The simulated world: an occupancy grid that rays can be cast into.

A :class:`World` is a boolean grid (``True`` = occupied) laid out as
:class:`~gridmap_cli.mapping.grid.GridSpec` describes it: shape (height, width), row 0 at the
bottom,
``origin`` the lower-left corner of cell (0, 0). Each occupied cell is a solid square of side
``resolution_m``.

Ray casting is sphere tracing on a Euclidean distance transform: from any point of a free cell the
nearest occupied square is at least ``edt - sqrt(2) * resolution`` away, so a ray can jump that far
without missing anything. Close to obstacles, where that bound is smaller than the way to the next
cell boundary, the ray walks cell by cell instead (Amanatides & Woo), so the hit lands exactly on
the boundary of the first occupied cell the ray enters. Every ray of a batch advances in lockstep
and finished rays are dropped from the batch, so the cost is the total number of steps, not the
number of rays times the longest ray.

Outside the grid is free space with nothing to hit: a ray leaving the grid never comes back and
reads no echo. (A wall there would invent echoes the world file does not show; worlds that need a
boundary draw it.)

Surface normals come from the gradient of a Gaussian-smoothed occupancy image, sampled half a cell
in front of the hit. Smoothing over a few cells recovers the direction of a straight wall that the
grid can only draw as a staircase, which a normal from the face the ray crossed (always axis-
aligned) or from the distance transform (pointing at single cell centres) would not.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from gridmap_cli.mapping.grid import GridSpec, OccupancyMap

FloatArray = npt.NDArray[np.float64]

#: Standard deviation (cells) of the smoothing behind surface normals. About two cells averages a
#: staircase wall over several steps (normals within ~2 deg of the true wall direction) while
#: keeping corners sharp to within a few cells.
NORMAL_SMOOTHING_CELLS = 2.0

#: Rays cast per batch: bounds the temporary arrays to a few tens of megabytes.
CAST_CHUNK = 1 << 18

#: How far past a cell boundary (cells) a cell-by-cell step lands, so that rounding rarely leaves
#: the next lookup short of the new cell. Far below any resolution anyone maps at.
_EPS_CELLS = 1e-9


class World:
    """An occupancy grid that rays can be cast into.

    Parameters
    ----------
    occupied
        Shape (height, width) matching ``spec.shape``; ``True`` marks an occupied cell. Row 0 is
        the bottom of the world (smallest y), as everywhere in gridmap.
    spec
        Where the grid lies in the world frame and its resolution.
    """

    def __init__(self, occupied: npt.ArrayLike, spec: GridSpec) -> None:
        occ = np.asarray(occupied)
        if occ.shape != spec.shape:
            raise ValueError(f"occupied has shape {occ.shape}, the grid spec says {spec.shape}")
        self.occupied: npt.NDArray[np.bool_] = occ.astype(bool)
        self.occupied.setflags(write=False)
        self.spec = spec
        h, w = spec.shape
        # Distance (cells) from each free cell centre to the nearest occupied cell centre. With
        # no occupied cell at all every ray is a miss: a distance beyond any ray lets it leave
        # the grid in one step.
        if self.occupied.any():
            edt = ndimage.distance_transform_edt(~self.occupied)
        else:
            edt = np.full(spec.shape, float(h + w + 2))
        # A step this long from anywhere in the cell cannot reach an occupied square (triangle
        # inequality: half a diagonal for the start point, half for the target square).
        # Occupied cells hold -1 so that one lookup answers both "hit?" and "how far may I go?".
        safe = np.maximum(edt - math.sqrt(2.0), 0.0)
        safe[self.occupied] = -1.0
        self._safe = np.ascontiguousarray(safe, dtype=np.float64).ravel()
        # "nearest" continues the grid's edge cells outwards, so a wall running off the edge of
        # the world keeps its direction there instead of fading into the free space outside.
        smooth = ndimage.gaussian_filter(
            self.occupied.astype(np.float64), NORMAL_SMOOTHING_CELLS, mode="nearest"
        )
        grad_row, grad_col = np.gradient(smooth)
        # The outward normal points down the occupancy gradient, from occupied into free space.
        self._normal_col = -grad_col
        self._normal_row = -grad_row

    @classmethod
    def from_occupancy_map(cls, occupancy: OccupancyMap, threshold: float = 0.5) -> World:
        """A world whose occupied cells are those with probability above ``threshold``.

        Unknown cells (NaN) are free: a simulated sonar should not echo off what a map never saw.
        """
        prob = np.nan_to_num(occupancy.prob, nan=0.0)
        return cls(prob > threshold, occupancy.spec)

    def occupied_at(self, x_m: npt.ArrayLike, y_m: npt.ArrayLike) -> npt.NDArray[np.bool_]:
        """Whether world points (metres, world frame, any broadcastable shapes) are occupied.

        Points outside the grid are free.
        """
        x, y = np.broadcast_arrays(np.asarray(x_m, dtype=np.float64), np.asarray(y_m, np.float64))
        col, row = self.spec.world_to_cell(x, y)
        h, w = self.spec.shape
        inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
        out = np.zeros(x.shape, dtype=bool)
        out[inside] = self.occupied[row[inside], col[inside]]
        return out

    def cast(
        self,
        x_m: npt.ArrayLike,
        y_m: npt.ArrayLike,
        angle_rad: npt.ArrayLike,
        max_range_m: npt.ArrayLike,
    ) -> tuple[FloatArray, FloatArray]:
        """Cast rays and return the distance to the first occupied cell and the incidence angle.

        Parameters
        ----------
        x_m, y_m
            Ray origins, metres, world frame.
        angle_rad
            Ray directions, radians, counter-clockwise from the world x axis.
        max_range_m
            How far each ray looks, metres.

        All four broadcast together to the rays' shape S (any shape, scalars included).

        Returns
        -------
        range_m
            Shape S, metres: the distance from the origin to the boundary of the first occupied
            cell along the ray, exact up to rounding; exactly ``max_range_m`` when the ray hits
            nothing within it. A ray starting inside an occupied cell reads 0.
        incidence_rad
            Shape S, radians in [0, pi/2]: angle between the reversed ray and the surface normal at
            the hit (0 = head-on, pi/2 = grazing); NaN where the ray hit nothing.
        """
        arrays = np.broadcast_arrays(
            np.asarray(x_m, dtype=np.float64),
            np.asarray(y_m, dtype=np.float64),
            np.asarray(angle_rad, dtype=np.float64),
            np.asarray(max_range_m, dtype=np.float64),
        )
        shape = arrays[0].shape
        x, y, a, rmax = (np.ascontiguousarray(v).ravel() for v in arrays)
        n = x.shape[0]
        range_m = np.empty(n, dtype=np.float64)
        incidence = np.empty(n, dtype=np.float64)
        for lo in range(0, n, CAST_CHUNK):
            hi = min(lo + CAST_CHUNK, n)
            range_m[lo:hi], incidence[lo:hi] = self._cast_flat(
                x[lo:hi], y[lo:hi], a[lo:hi], rmax[lo:hi]
            )
        return range_m.reshape(shape), incidence.reshape(shape)

    def _cast_flat(
        self, x_m: FloatArray, y_m: FloatArray, angle_rad: FloatArray, max_range_m: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """:meth:`cast` on flat arrays of shape (R,)."""
        spec = self.spec
        res = spec.resolution_m
        h, w = spec.shape
        # Work in cell units with the grid's corner at (0, 0): cell (col, row) is the unit square
        # [col, col+1) x [row, row+1), so a cell index is a floor and a range a product.
        u0 = (x_m - spec.origin_x_m) / res
        v0 = (y_m - spec.origin_y_m) / res
        # Direction components below 1e-15 become 1e-15 (keeping their sign): the ray turns by
        # less than 1e-15 rad, and the reciprocals below stay finite (no 0 * inf).
        du = _away_from_zero(np.cos(angle_rad))
        dv = _away_from_zero(np.sin(angle_rad))
        t_max = np.maximum(max_range_m, 0.0) / res
        t_in, t_out = _clip_to_box(u0, v0, du, dv, float(w), float(h))
        t_end = np.minimum(t_out, t_max)
        n = u0.shape[0]
        t_hit = np.full(n, np.inf)
        ids = np.flatnonzero(t_in <= t_end)
        t = t_in[ids]
        u0, v0, du, dv, t_end = u0[ids], v0[ids], du[ids], dv[ids], t_end[ids]
        inv_du = 1.0 / np.abs(du)
        inv_dv = 1.0 / np.abs(dv)
        neg_u = du < 0.0
        neg_v = dv < 0.0
        safe = self._safe
        while ids.shape[0]:
            pu = u0 + t * du
            pv = v0 + t * dv
            col = _cell_ahead(pu, neg_u, w)
            row = _cell_ahead(pv, neg_v, h)
            step = safe[row * w + col]
            hit = step < 0.0
            # Distance to the next cell boundary along the ray: walking there never skips a
            # cell, and with the cell taken ahead of a boundary it is never zero.
            frac_u = pu - col
            frac_v = pv - row
            to_u = np.where(neg_u, frac_u, 1.0 - frac_u) * inv_du
            to_v = np.where(neg_v, frac_v, 1.0 - frac_v) * inv_dv
            np.maximum(step, np.minimum(to_u, to_v) + _EPS_CELLS, out=step)
            t_hit[ids[hit]] = t[hit]
            t += step
            keep = ~hit & (t < t_end)
            if not keep.all():
                ids, t = ids[keep], t[keep]
                u0, v0, du, dv, t_end = u0[keep], v0[keep], du[keep], dv[keep], t_end[keep]
                inv_du, inv_dv, neg_u, neg_v = inv_du[keep], inv_dv[keep], neg_u[keep], neg_v[keep]
        got = np.isfinite(t_hit)
        range_m = np.where(got, np.maximum(t_hit, 0.0) * res, max_range_m)
        # the hit's overshoot past the boundary is about 1e-9 cells; never report a hit
        # beyond the ray's own maximum
        range_m = np.minimum(range_m, max_range_m)
        incidence = np.full(n, np.nan)
        if got.any():
            incidence[got] = self._incidence(
                (x_m[got] - spec.origin_x_m) / res,
                (y_m[got] - spec.origin_y_m) / res,
                angle_rad[got],
                t_hit[got],
            )
        return range_m, incidence

    def _incidence(
        self, u0: FloatArray, v0: FloatArray, angle_rad: FloatArray, t_hit: FloatArray
    ) -> FloatArray:
        """Incidence angles (radians, shape (K,)) of rays that hit at ``t_hit`` (cells)."""
        du = np.cos(angle_rad)
        dv = np.sin(angle_rad)
        # Half a cell in front of the hit: on the free side, where the smoothed occupancy rises
        # steadily towards the obstacle even for a wall one cell thick.
        back = np.maximum(t_hit - 0.5, 0.0)
        nu = _bilinear(self._normal_col, u0 + back * du, v0 + back * dv)
        nv = _bilinear(self._normal_row, u0 + back * du, v0 + back * dv)
        norm = np.hypot(nu, nv)
        with np.errstate(invalid="ignore", divide="ignore"):
            cos_inc = -(nu * du + nv * dv) / norm
        # No gradient (a ray starting deep inside a solid block): call it head-on.
        cos_inc = np.where(norm > 1e-12, np.abs(cos_inc), 1.0)
        return np.arccos(np.clip(cos_inc, 0.0, 1.0))


def _away_from_zero(d: FloatArray) -> FloatArray:
    """``d`` (shape (R,)) with magnitudes below 1e-15 raised to 1e-15, signs kept (0 -> +)."""
    return np.where(np.abs(d) < 1e-15, np.where(d < 0.0, -1e-15, 1e-15), d)


def _cell_ahead(p: FloatArray, negative: npt.NDArray[np.bool_], size: int) -> npt.NDArray[np.int64]:
    """Index (shape (R,)) of the cell a ray at coordinate ``p`` (cells) is about to traverse.

    On a cell boundary that is the cell on the side the ray moves to: ``floor(p)`` moving up,
    ``ceil(p) - 1`` moving down. Taking ``floor`` regardless would leave a ray moving down on a
    boundary with zero distance to its "next" boundary, and it would crawl. Clipped to the grid,
    which only matters at its edges.
    """
    i = p.astype(np.int64)  # floor, since p >= 0 up to rounding
    i -= negative & (i == p)
    return np.clip(i, 0, size - 1)


def _clip_to_box(
    u0: FloatArray, v0: FloatArray, du: FloatArray, dv: FloatArray, width: float, height: float
) -> tuple[FloatArray, FloatArray]:
    """Ray parameters (cells, shape (R,)) where rays enter and leave [0, width] x [0, height].

    ``t_in`` is never negative (a ray starting inside enters at 0); ``t_in > t_out`` means the
    ray misses the box.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_u = 1.0 / du
        inv_v = 1.0 / dv
        a_u = (0.0 - u0) * inv_u
        b_u = (width - u0) * inv_u
        a_v = (0.0 - v0) * inv_v
        b_v = (height - v0) * inv_v
    # A ray parallel to an axis is inside that slab for all t or for none.
    inside_u = (u0 >= 0.0) & (u0 <= width)
    inside_v = (v0 >= 0.0) & (v0 <= height)
    par_u = du == 0.0
    par_v = dv == 0.0
    lo_u = np.where(par_u, np.where(inside_u, -np.inf, np.inf), np.minimum(a_u, b_u))
    hi_u = np.where(par_u, np.where(inside_u, np.inf, -np.inf), np.maximum(a_u, b_u))
    lo_v = np.where(par_v, np.where(inside_v, -np.inf, np.inf), np.minimum(a_v, b_v))
    hi_v = np.where(par_v, np.where(inside_v, np.inf, -np.inf), np.maximum(a_v, b_v))
    t_in = np.maximum(np.maximum(lo_u, lo_v), 0.0)
    t_out = np.minimum(hi_u, hi_v)
    return t_in, t_out


def _bilinear(image: FloatArray, u: FloatArray, v: FloatArray) -> FloatArray:
    """Bilinear interpolation of a per-cell image (shape (H, W), values at cell centres).

    ``u``, ``v``: points in cell units (cell (c, r) spans [c, c+1) x [r, r+1)); outside the
    image the nearest edge value is used.
    """
    h, w = image.shape
    fu = np.clip(u - 0.5, 0.0, w - 1.0)
    fv = np.clip(v - 0.5, 0.0, h - 1.0)
    c0 = np.minimum(fu.astype(np.int64), max(w - 2, 0))
    r0 = np.minimum(fv.astype(np.int64), max(h - 2, 0))
    c1 = np.minimum(c0 + 1, w - 1)
    r1 = np.minimum(r0 + 1, h - 1)
    au = fu - c0
    av = fv - r0
    top = image[r1, c0] * (1.0 - au) + image[r1, c1] * au
    bottom = image[r0, c0] * (1.0 - au) + image[r0, c1] * au
    return np.asarray(bottom * (1.0 - av) + top * av, dtype=np.float64)
