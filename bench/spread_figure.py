"""docs/images/spread-layer.png: two ``--draw-path`` previews of one log side by side, the maps
shrunk to one height and the first preview's legend kept at full size under them.

    L=../shared/data/carmen/intel-corrected.log.gz
    gridmap calibrate $L -o odo.yaml
    gridmap build $L -o aware.png --mode error-aware --odometry-error odo.yaml --draw-path \\
        --map-mode scale
    gridmap build $L -o slam.png --pose slam --draw-path
    .venv/bin/python bench/spread_figure.py aware_path.png aware.png slam_path.png slam.png
"""

from __future__ import annotations

import sys
from pathlib import Path

from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "images" / "spread-layer.png"
HEIGHT_PX = 360


def main(argv: list[str]) -> None:
    previews = [Image.open(p).convert("RGB") for p in argv[0::2]]
    heights = [Image.open(m).height for m in argv[1::2]]
    maps = [p.crop((0, 0, Image.open(m).width, h)) for p, m, h in
            zip(previews, argv[1::2], heights, strict=True)]  # fmt: skip
    shrunk = [m.resize((round(m.width * HEIGHT_PX / m.height), HEIGHT_PX), Image.LANCZOS)
              for m in maps]  # fmt: skip
    legend = previews[0].crop((0, heights[0], previews[0].width, previews[0].height))
    legend = legend.crop((0, 0, min(legend.width, 420), legend.height))
    width = sum(m.width for m in shrunk) + 8 * (len(shrunk) - 1)
    out = Image.new("RGB", (max(width, legend.width), HEIGHT_PX + legend.height), "white")
    x = 0
    for m in shrunk:
        out.paste(m, (x, 0))
        x += m.width + 8
    out.paste(legend, (0, HEIGHT_PX))
    out.save(OUT, optimize=True)
    print(f"wrote {OUT} ({OUT.stat().st_size:,} bytes)")


if __name__ == "__main__":
    main(sys.argv[1:])
