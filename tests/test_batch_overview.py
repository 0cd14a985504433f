"""``gridmap batch`` writes OUTDIR/index.html on every run; a real browser (headless Chromium)
renders it from file:// and from a static web server, and its thumbnails decode.

The browser tests skip where no Chromium is installed (``.ci/run`` installs Debian's
``chromium`` when it can)."""

from __future__ import annotations

import functools
import http.server
import re
import shutil
import subprocess
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from gridmap_cli.runs.batch import OVERVIEW_NAME
from tests.helpers import run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
#: A bound that catches a hung browser, not a slow machine.
BROWSER_TIMEOUT_S = 120

#: Appended to a copy of the page: what the browser made of it, written into the DOM.
CHECK_SCRIPT = """
<script>
window.addEventListener("load", async () => {
  const images = [...document.images];
  const decoded = images.filter((i) => i.complete && i.naturalWidth > 0).length;
  document.body.setAttribute("data-decoded", `${decoded}/${images.length}`);
  const links = [...document.querySelectorAll("a[href]")]
    .map((a) => a.getAttribute("href")).filter((h) => !h.startsWith("#"));
  const statuses = [];
  for (const href of new Set(links)) {
    try { statuses.push((await fetch(href)).status); } catch (e) { statuses.push("x"); }
  }
  document.body.setAttribute("data-links", statuses.join(","));
  document.body.setAttribute("data-done", "yes");
});
</script>
"""


def browser() -> str | None:
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.fixture
def logs(tmp_path: Path) -> Path:
    folder = tmp_path / "logs"
    folder.mkdir()
    for name in ("hall.csv", "office.csv"):
        shutil.copy(SAMPLES / name, folder / name)
    shutil.copy(SAMPLES / "corridor_loop.csv", folder / "a <b> & c.csv")
    (folder / "broken.csv").write_text("time,x,y,theta,sonar0\n0,0,0,0,1\n0,0,0\n")
    return folder


def test_every_run_writes_the_overview_built_up_to_date_and_failed(
    logs: Path, tmp_path: Path
) -> None:
    out = tmp_path / "maps"
    code, _, err = run("batch", str(logs), "-o", str(out))
    assert code == 1
    assert f"(overview: {out / OVERVIEW_NAME})" in err
    first = (out / OVERVIEW_NAME).read_text()
    assert first.count('<article class="card') == 4
    assert first.count('class="badge built">built') == 3
    assert first.count('class="badge failed">failed') == 1
    assert first.count("data:image/png;base64,") == 3
    assert "a &lt;b&gt; &amp; c.csv" in first and "a <b>" not in first
    assert "broken.csv:3:" in first  # the failed log's error line
    assert not [p for p in out.iterdir() if ".tmp-" in p.name]  # written atomically
    # an up-to-date run regenerates it, thumbnails and all, from the sidecars
    code, _, _ = run("batch", str(logs), "-o", str(out))
    second = (out / OVERVIEW_NAME).read_text()
    assert second.count('class="badge skipped">up to date') == 3
    assert second.count("data:image/png;base64,") == 3
    assert "broken.csv:3:" in second
    thumbs = re.findall(r'src="(data:image/png;base64,[^"]+)"', first)
    assert re.findall(r'src="(data:image/png;base64,[^"]+)"', second) == thumbs


def _dump_dom(url: str, profile: Path) -> str:
    chromium = browser()
    assert chromium is not None
    done = subprocess.run(
        [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
         f"--user-data-dir={profile}", "--virtual-time-budget=20000", "--dump-dom", url],
        capture_output=True, text=True, timeout=BROWSER_TIMEOUT_S, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


@pytest.fixture
def checked_page(logs: Path, tmp_path: Path) -> Path:
    """A batch's folder holding check.html: the overview with :data:`CHECK_SCRIPT`."""
    if browser() is None:
        pytest.skip("no Chromium installed (Debian: apt-get install chromium)")
    out = tmp_path / "maps"
    assert run("batch", str(logs), "-o", str(out), "-q")[0] == 1
    page = (out / OVERVIEW_NAME).read_text()
    (out / "check.html").write_text(page.replace("</body>", CHECK_SCRIPT + "</body>"))
    return out


def test_chromium_renders_the_overview_from_a_file_and_decodes_every_thumbnail(
    checked_page: Path, tmp_path: Path
) -> None:
    dom = _dump_dom((checked_page / "check.html").as_uri(), tmp_path / "profile")
    assert 'data-decoded="3/3"' in dom
    assert dom.count('<article class="card') == 4


@pytest.fixture
def served(checked_page: Path) -> Iterator[str]:
    handler = functools.partial(_QuietHandler, directory=str(checked_page))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()
        thread.join()


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:
        return None


def test_chromium_renders_it_from_a_static_server_and_every_link_resolves(
    served: str, tmp_path: Path
) -> None:
    dom = _dump_dom(f"{served}/check.html", tmp_path / "profile")
    assert 'data-decoded="3/3"' in dom and 'data-done="yes"' in dom
    links = re.search(r'data-links="([^"]*)"', dom)
    assert links is not None
    statuses = links.group(1).split(",")
    # three maps' image and YAML, and the report
    assert statuses == ["200"] * 7, statuses


def test_the_quality_block_reads_as_a_few_words() -> None:
    from gridmap_cli.writers.overview import quality_text

    quality = {
        "spread": {"share_within_m": {"0.1": 0.25, "0.5": 0.9, "1": 1.0}},
        "echo_consistency": {"echoes": 10, "in_free": 0.1234, "in_occupied": 0.5},
        "closures": {"closures": 12, "median_nees": 0.05, "expected_median": 2.366},
        "revisits": {"relations": 12, "median_m": 0.0312, "mean_m": 0.0415, "held_out": True},
    }
    assert quality_text(quality) == (
        "pose spread within 0.1 m: 25 %, 0.5 m: 90 %, 1 m: 100 %; 12.3 % of laser echoes in free "
        "cells; revisits 0.04 m apart (mean of 12); 12 closures, median NEES 0.05"
    )
    # a sonar log's standard map: nothing to say, no line on its card
    assert quality_text({"spread": None, "echo_consistency": None, "closures": None}) == ""
    assert quality_text(None) == ""
