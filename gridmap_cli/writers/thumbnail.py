"""A small picture of a map for people (batch's overview page), never a map_server image.

The map is shrunk by a whole factor so that its longer side fits :data:`THUMBNAIL_PX`; each
block of cells becomes one pixel, occupied if any of its cells is (a one-cell wall survives the
shrinking, as it does in a person's sketch), else free if any is, else unknown: the trinary
greys of the map image. Maps smaller than the limit keep one pixel per cell (the page scales
them up without smoothing).
"""

from __future__ import annotations

import io
import math

import numpy as np
import numpy.typing as npt
from PIL import Image

from gridmap_cli.writers.map_image import FREE_GREY, OCCUPIED_GREY, UNKNOWN_GREY

#: The longer side of a thumbnail, in pixels.
THUMBNAIL_PX = 240


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
    pooled = []
    for mask in (prob >= occupied, prob <= free):  # NaN compares False: unknown is neither
        padded = np.zeros((rows * k, cols * k), dtype=bool)
        padded[:height, :width] = mask
        pooled.append(padded.reshape(rows, k, cols, k).any(axis=(1, 3)))
    grey = np.full((rows, cols), UNKNOWN_GREY, dtype=np.uint8)
    grey[pooled[1]] = FREE_GREY
    grey[pooled[0]] = OCCUPIED_GREY  # any occupied cell in a block, else any free one
    return np.ascontiguousarray(grey[::-1])


def thumbnail_png(
    prob: npt.NDArray[np.float64], occupied: float, free: float, size_px: int = THUMBNAIL_PX
) -> bytes:
    """:func:`thumbnail_pixels` as the bytes of an 8-bit grey PNG."""
    buffer = io.BytesIO()
    Image.fromarray(thumbnail_pixels(prob, occupied, free, size_px)).save(buffer, format="PNG")
    return buffer.getvalue()
