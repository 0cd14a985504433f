"""The beam directions of a laser whose scans do not all share one geometry.

A laser's beams are ray sensors ``<laser>_<i>`` (:func:`~gridmap_cli.robot.laser_beams`), one
per direction. Real lasers do not always keep one geometry: some interleave scans with several
start angles (a SICK LMS's quarter-degree mode sends four scans a quarter step apart), some add
or drop a beam now and then. Each scan is then read with its own geometry, and each of its beams
becomes the sensor of its own direction: the first scan's beams are ``<laser>_0`` ..
``<laser>_<n-1>`` as for any laser, and a beam pointing where no beam pointed before is a new
sensor, numbered on. A beam pointing where one already did (within :func:`bin_width_rad`) is that
sensor, so a scan one beam longer adds one sensor, and four interleaved start angles four times
the beams, however long the log.

The canonical record stream stays (stamp, sensor, range): every later stage (sync, the sensor
models, scan matching) finds each reading's bearing in its sensor, as for any laser.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

IntArray = npt.NDArray[np.int64]

#: Beams whose directions differ by less than this are one sensor: a tenth of a milliradian, 3 mm
#: at 30 m, well under any scanning laser's step; it bounds a laser whose driver jitters its
#: start angle at 2 pi / BIN_RAD sensors.
BIN_RAD = 1e-4
_EDGE = 0.3819660112501051  # where a bin's edge lies, in bins: far from any simple fraction
#: Geometries remembered at once (a driver may jitter its angles at every scan).
_CACHED = 64


def bin_width_rad(step_rad: float) -> float:
    """The angular bin of one beam direction: :data:`BIN_RAD`, or an eighth of the first scan's
    step when that is finer, so that no two beams of one scan, nor beams interleaved a quarter
    step apart, fall in one bin."""
    step = abs(step_rad)
    return min(BIN_RAD, step / 8.0) if step > 0.0 and math.isfinite(step) else BIN_RAD


class BeamBook:
    """The beam sensors of one laser: which sensor each beam of a scan is.

    Built from the first scan's geometry (``start``, ``step`` in radians, ``count`` beams):
    its beam ``i`` is sensor ``i``. Each sensor keeps the geometry that made it
    (:attr:`start`, :attr:`step`, :attr:`local`: its direction is ``start + local * step`` in
    the laser frame), so a reader computes its yaw with the same arithmetic as the first
    scan's beams, to the bit.
    """

    def __init__(self, start: float, step: float, count: int) -> None:
        self.first = (start, step, count)
        self.width = bin_width_rad(step)
        local = np.arange(count, dtype=np.int64)
        self.start = np.full(count, start, dtype=np.float64)
        self.step = np.full(count, step, dtype=np.float64)
        self.local = local
        bins = self._bins(start, step, count)
        order = np.argsort(bins, kind="stable")
        self._bins_sorted = bins[order]
        self._sensor_of_bin = local[order]
        self._known: dict[tuple[float, float, int], IntArray] = {self.first: local}
        #: whether any scan had another geometry than the first
        self.varied = False

    def __len__(self) -> int:
        return len(self.local)

    def _bins(self, start: float, step: float, count: int) -> IntArray:
        bearing = start + np.arange(count, dtype=np.float64) * step
        # bin edges off round numbers: a decimal step (0.0174530) must not put a direction
        # exactly on an edge, where rounding noise would split it from itself
        return np.floor(bearing / self.width + _EDGE).astype(np.int64)

    def sensors(self, start: float, step: float, count: int) -> IntArray:
        """The sensor of each beam of a scan of ``count`` beams from ``start`` by ``step``
        (shape (count,)); directions not seen before become new sensors, in beam order."""
        key = (start, step, count)
        known = self._known.get(key)
        if known is not None:
            return known
        self.varied = True
        bins = self._bins(start, step, count)
        at = np.searchsorted(self._bins_sorted, bins)
        found = at < len(self._bins_sorted)
        found[found] = self._bins_sorted[at[found]] == bins[found]
        out = np.empty(count, dtype=np.int64)
        out[found] = self._sensor_of_bin[at[found]]
        new_bins, first_beam, inverse = np.unique(
            bins[~found], return_index=True, return_inverse=True
        )
        if len(new_bins):
            # numbered in beam order: by the first beam of the scan that points there
            by_beam = np.argsort(first_beam, kind="stable")
            fresh = np.empty(len(new_bins), dtype=np.int64)
            fresh[by_beam] = len(self.local) + np.arange(len(new_bins), dtype=np.int64)
            out[~found] = fresh[inverse.reshape(-1)]
            beams = np.flatnonzero(~found)[first_beam[by_beam]]
            self.start = np.concatenate((self.start, np.full(len(beams), start)))
            self.step = np.concatenate((self.step, np.full(len(beams), step)))
            self.local = np.concatenate((self.local, beams.astype(np.int64)))
            merged = np.concatenate((self._bins_sorted, new_bins))
            order = np.argsort(merged, kind="stable")
            self._bins_sorted = merged[order]
            self._sensor_of_bin = np.concatenate((self._sensor_of_bin, fresh))[order]
        if len(self._known) >= _CACHED:
            self._known = {self.first: self._known[self.first]}
        self._known[key] = out
        return out
