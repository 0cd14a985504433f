"""A small picture of a map for people (batch's overview page), never a map_server image.

The map is shrunk by a whole factor k so that its longer side fits :data:`THUMBNAIL_PX`; each
k x k block of cells becomes one pixel, occupied when at least k / 2 of its cells are (a wall
one cell thick crosses k of them, so it survives the shrinking, as in a person's sketch, while
a stray occupied cell does not blacken a room), else free if any cell is, else unknown: the
trinary greys of the map image. Maps smaller than the limit keep one pixel per cell (the page scales
small ones up without smoothing).
"""

from __future__ import annotations

import io
import math

import numpy as np
import numpy.typing as npt
from PIL import Image

from gridmap_cli.writers.map_image import FREE_GREY, OCCUPIED_GREY, UNKNOWN_GREY

#: The longer side of a thumbnail, in pixels.
THUMBNAIL_PX = 320


def thumbnail_pixels(
    prob: npt.NDArray[np.float64], occupied: float, free: float, size_px: int = THUMBNAIL_PX
) -> npt.NDArray[np.uint8]:
    """The thumbnail of a probability map as grey pixels, top row first.

    ``prob``: shape (height, width), row 0 the bottom of the map, values in [0, 1], NaN
    unknown; ``occupied`` / ``free``: the trinary thresholds. Returns uint8 of shape
    (ceil(height / k), ceil(width / k)) with k = ceil(max(height, width) / size_px).
    """
    height, width = prob.shape
    k = max(1, math.ceil(max(height, width) / size_px))
    rows, cols = math.ceil(height / k), math.ceil(width / k)
    counts = []
    for mask in (prob >= occupied, prob <= free):  # NaN compares False: unknown is neither
        padded = np.zeros((rows * k, cols * k), dtype=bool)
        padded[:height, :width] = mask
        counts.append(padded.reshape(rows, k, cols, k).sum(axis=(1, 3), dtype=np.int32))
    grey = np.full((rows, cols), UNKNOWN_GREY, dtype=np.uint8)
    grey[counts[1] > 0] = FREE_GREY
    grey[counts[0] >= max(1, k // 2)] = OCCUPIED_GREY
    return np.ascontiguousarray(grey[::-1])


def thumbnail_png(
    prob: npt.NDArray[np.float64], occupied: float, free: float, size_px: int = THUMBNAIL_PX
) -> bytes:
    """:func:`thumbnail_pixels` as the bytes of an 8-bit grey PNG."""
    buffer = io.BytesIO()
    Image.fromarray(thumbnail_pixels(prob, occupied, free, size_px)).save(buffer, format="PNG")
    return buffer.getvalue()
