"""The picture of an evaluation: the map in the world with the true walls over it, and a
reliability diagram. matplotlib is an optional extra (``pip install 'gridmap-cli[plot]'``)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import numpy.typing as npt

from gridmap_cli.atomic import atomic_output
from gridmap_cli.errors import GridmapError
from gridmap_cli.evaluation.evaluate import Evaluation
from gridmap_cli.mapping.grid import GridSpec


class PlotUnavailableError(GridmapError):
    """matplotlib is not installed."""


def check_plotting(flag: str = "--plot") -> None:
    """Raise :class:`PlotUnavailableError` unless matplotlib can be imported; the message names
    ``flag``, the option that asked for a figure, and how to install the extra."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise PlotUnavailableError(
            f"{flag} needs matplotlib, an optional extra: pip install 'gridmap-cli[plot]'"
        ) from None


#: Colour of the cells a map does not know (or does not reach) in :func:`map_rgb`.
UNKNOWN_RGB = (0.85, 0.9, 1.0)


def map_rgb(p_world: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """A probability map as an image: grey = 1 - p (occupied is dark), NaN (unknown) pale blue.

    ``p_world`` shape (H, W); returns RGB floats in [0, 1], shape (H, W, 3), rows as given.
    """
    rgb = np.repeat((1.0 - np.nan_to_num(p_world, nan=0.0))[:, :, None], 3, axis=2)
    rgb[np.isnan(p_world)] = UNKNOWN_RGB
    return rgb


def plot_evaluation(
    path: Path,
    evaluation: Evaluation,
    walls: npt.NDArray[np.bool_],
    region: npt.NDArray[np.bool_],
    world: GridSpec,
    title: str = "",
) -> None:
    """Write a PNG: left the map's probabilities on the world grid (grey = 1 - p, unknown pale
    blue) with the true walls in red and the scored region's edge in green; right the
    reliability diagram. Arrays shape ``world.shape``, row 0 at the bottom."""
    check_plotting()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy import ndimage

    rgb = map_rgb(evaluation.p_world)
    edge = region & ~ndimage.binary_erosion(region)
    rgb[edge & ~walls] = (0.2, 0.7, 0.2)
    overlay = np.zeros((*walls.shape, 4))
    overlay[walls] = (0.9, 0.1, 0.1, 0.55)
    extent = (
        world.origin_x_m,
        world.origin_x_m + world.width * world.resolution_m,
        world.origin_y_m,
        world.origin_y_m + world.height * world.resolution_m,
    )
    aspect = world.width / max(world.height, 1)
    fig, (ax_map, ax_rel) = plt.subplots(
        1, 2, figsize=(5.0 * aspect + 5.0, 5.6), gridspec_kw={"width_ratios": [aspect, 1.0]}
    )
    ax_map.imshow(rgb, origin="lower", extent=extent, interpolation="nearest")
    ax_map.imshow(overlay, origin="lower", extent=extent, interpolation="nearest")
    ax_map.set_xlabel("x (m, world)")
    ax_map.set_ylabel("y (m, world)")
    e = evaluation
    ax_map.set_title(
        f"{title}\nNLL {e.nll:.3f}  Brier {e.brier:.3f}  ECE {e.ece:.3f}  F1 {e.f1:.2f}  "
        f"coverage {e.coverage:.2f}".strip(),
        fontsize=9,
    )
    used = [b for b in e.reliability if b.count]
    centres = [(b.lower + b.upper) / 2 for b in e.reliability]
    ax_rel.plot([0, 1], [0, 1], color="0.6", linestyle="--", linewidth=1, label="calibrated")
    ax_rel.plot(
        [b.mean_predicted for b in used],
        [b.observed_frequency for b in used],
        marker="o",
        color="tab:blue",
        label="map",
    )
    ax_rel.set_xlim(0, 1)
    ax_rel.set_ylim(0, 1)
    ax_rel.set_xlabel("predicted p (bin mean)")
    ax_rel.set_ylabel("observed frequency of occupied")
    ax_rel.set_title(f"reliability (ECE {e.ece:.3f})", fontsize=9)
    counts = ax_rel.twinx()
    counts.bar(
        centres,
        [max(b.count, 0) for b in e.reliability],
        width=0.09,
        color="tab:orange",
        alpha=0.3,
        log=True,
    )
    counts.set_ylabel("cells per bin (log)")
    counts.set_ylim(0.8, max(10.0, 10 ** math.ceil(math.log10(max(e.cells, 1)))))
    ax_rel.set_zorder(counts.get_zorder() + 1)
    ax_rel.patch.set_visible(False)
    ax_rel.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    with atomic_output(path) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)


def plot_pose_spread(
    path: Path,
    p_world: npt.NDArray[np.float64],
    position_m: npt.NDArray[np.float64],
    heading_deg: npt.NDArray[np.float64],
    walls: npt.NDArray[np.bool_],
    world: GridSpec,
    title: str = "",
    max_heading_deg: float | None = None,
) -> None:
    """Write a PNG of where the map's uncertainty comes from, three panels on the world grid:
    the map (grey = 1 - p, unknown pale blue, true walls in red); the smallest position spread
    (metres, one standard deviation) of the pose at which a reading's beam crossed each cell;
    the heading spread (degrees) of those readings, with ``max_heading_deg`` (the build's limit,
    if any) marked on its colour bar. Cells the map knows that none of the drawn rays crossed
    (between a sonar cone's rays, or reached only by the expected map's sampled tracks) are mid
    grey; cells the map does not know are pale blue. Arrays shape
    ``world.shape``, row 0 at the bottom.
    """
    check_plotting()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    extent = (
        world.origin_x_m,
        world.origin_x_m + world.width * world.resolution_m,
        world.origin_y_m,
        world.origin_y_m + world.height * world.resolution_m,
    )
    aspect = world.width / max(world.height, 1)
    fig, axes = plt.subplots(1, 3, figsize=(3 * 4.2 * aspect + 2.4, 5.4), squeeze=False)
    ax_map, ax_f, ax_g = axes[0]
    rgb = map_rgb(p_world)
    rgb[walls] = 0.5 * rgb[walls] + 0.5 * np.array([0.95, 0.1, 0.1])
    ax_map.imshow(rgb, origin="lower", extent=extent, interpolation="nearest")
    ax_map.set_title(
        "map (grey = 1 - p), true walls red\nspread panels: mid grey = known, but crossed by "
        "no drawn ray",
        fontsize=9,
    )
    if title:
        fig.suptitle(title, fontsize=10)
    panels = (
        (
            ax_f,
            position_m,
            "smallest position spread (m, 1 sigma)\nof the readings that crossed a cell",
            None,
        ),
        (ax_g, heading_deg, "heading spread (deg, 1 sigma) of those readings", max_heading_deg),
    )
    for ax, values, label, limit in panels:
        ax.set_facecolor(UNKNOWN_RGB)
        values = np.where(np.isnan(p_world), np.nan, values)
        seen = values[np.isfinite(values)]
        top = float(seen.max()) if seen.size else 1.0
        image = ax.imshow(
            np.ma.masked_invalid(values),
            origin="lower",
            extent=extent,
            interpolation="nearest",
            cmap="viridis",
            vmin=0.0,
            vmax=max(top, 1e-9),
        )
        # cells the map knows only through a wedge widened by g (no beam axis crossed them)
        widened = ~np.isnan(p_world) & np.isnan(values)
        shade = np.zeros((*widened.shape, 4))
        shade[widened] = (0.55, 0.55, 0.55, 1.0)
        ax.imshow(shade, origin="lower", extent=extent, interpolation="nearest")
        bar = fig.colorbar(image, ax=ax, fraction=0.046, pad=0.03)
        if limit is not None and math.isfinite(limit) and limit <= top:
            bar.ax.axhline(limit, color="red", linewidth=2)
            label += f"\n(red: the build's limit, {limit:g} deg)"
        ax.set_title(label, fontsize=9)
    for ax in axes[0]:
        ax.set_xlabel("x (m, world)")
        ax.set_ylabel("y (m, world)")
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.92))
    with atomic_output(path) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)
