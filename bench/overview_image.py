"""docs/images/batch-overview.png: a screenshot of a real ``gridmap batch`` overview page.

Two nightly runs over the CARMEN logs of ../shared/data (when present) and the bundled samples:
the second run finds a new log, a log that cannot be mapped and the rest up to date, so the
page shows every status. Headless Chromium takes the screenshot (Debian: ``apt-get install
chromium``). Run with ``make overview-image``.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
TARGET = ROOT / "docs" / "images" / "batch-overview.png"


def main() -> int:
    chromium = next(
        (p for n in ("chromium", "chromium-browser", "google-chrome") if (p := shutil.which(n))),
        None,
    )
    if chromium is None:
        print("no Chromium: apt-get install chromium", file=sys.stderr)
        return 1
    gridmap = str(Path(sys.executable).with_name("gridmap"))
    with tempfile.TemporaryDirectory(prefix="gridmap-overview-") as folder:
        logs, maps = Path(folder) / "logs", Path(folder) / "maps"
        logs.mkdir()
        first = [p for p in sorted((ROOT / "samples").glob("*.csv")) if "corridor" not in p.name]
        first += sorted((DATA / "carmen").glob("*.log.gz")) if DATA.is_dir() else []
        for log in first:
            shutil.copy(log, logs / log.name)
        run = [gridmap, "batch", str(logs), "-o", str(maps), "--pose", "global", "--jobs", "2"]
        subprocess.run(run, check=False)
        shutil.copy(ROOT / "samples" / "corridor_loop.mcap", logs / "corridor_loop.mcap")
        (logs / "truncated.csv").write_text("time,x,y,theta,sonar0\n0,0,0,0,1\n0.1,0,0\n")
        subprocess.run(run, check=False)
        subprocess.run(
            [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
             f"--user-data-dir={Path(folder) / 'profile'}", "--window-size=1280,1180",
             f"--screenshot={TARGET}", (maps / "index.html").as_uri()],
            check=True, capture_output=True, timeout=120,
        )  # fmt: skip
    print(f"wrote {TARGET}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
