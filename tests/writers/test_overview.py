"""The batch overview page as a pure function, and the thumbnails on it."""

from __future__ import annotations

import base64
import io
import re
from html.parser import HTMLParser

import numpy as np
from PIL import Image

from gridmap_cli.writers.overview import OverviewPage, overview_html, png_size
from gridmap_cli.writers.thumbnail import thumbnail_pixels, thumbnail_png

VOID = {"meta", "img", "br", "hr", "link", "input"}


class Page(HTMLParser):
    """Tags, attributes and text of a page; raises on a closing tag that closes nothing open."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.open: list[str] = []
        self.attrs: list[tuple[str, dict[str, str | None]]] = []
        self.text: list[str] = []
        self.feed(text)
        self.close()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.attrs.append((tag, dict(attrs)))
        if tag not in VOID:
            self.open.append(tag)

    def handle_endtag(self, tag: str) -> None:
        assert self.open and self.open[-1] == tag, (tag, self.open)
        self.open.pop()

    def handle_data(self, data: str) -> None:
        self.text.append(data)

    def tags(self, tag: str, **wanted: str) -> list[dict[str, str | None]]:
        return [
            a for t, a in self.attrs
            if t == tag and all(wanted[k] in (a.get(k) or "").split() for k in wanted)
        ]  # fmt: skip


def thumb(width: int, height: int) -> bytes:
    prob = np.full((height, width), 0.1)
    prob[0, :] = 0.9
    return thumbnail_png(prob, 0.65, 0.25)


PAGE = OverviewPage(
    folder="/data/maps",
    report="/data/maps/batch-report.jsonl",
    generated="2026-12-02 07:00:00 UTC",
    seconds=12.5,
    resolution_m=0.05,
    version="9.9",
    total=3,
    options=(("pose", "odometry"),),
)


def records() -> list[dict[str, object]]:
    return [
        {"log": "/data/logs/a.csv", "map": "/data/maps/a.png", "status": "built", "error": None,
         "seconds": {"total": 2.25}, "cells": {"width": 400, "height": 200}, "readings": 12345,
         "warnings": ["3 columns left out"], "built_at": "2026-12-02T06:59:00Z"},
        {"log": "/data/logs/b.mcap", "map": "/data/maps/b.png", "status": "skipped",
         "error": None, "seconds": {"total": 0.01}, "cells": {"width": 10, "height": 20},
         "readings": 7, "warnings": [], "built_at": "2026-12-01T06:59:00Z"},
        {"log": "/data/logs/c.bag", "map": "/data/maps/c.png", "status": "failed",
         "error": "/data/logs/c.bag: byte 3000: bad CRC", "seconds": {"total": 0.5},
         "cells": {}, "readings": 0, "warnings": [], "built_at": ""},
    ]  # fmt: skip


def test_one_card_per_log_failed_first_with_what_a_reader_needs() -> None:
    a, b = thumb(40, 20), thumb(10, 20)
    text = overview_html(records(), {"/data/maps/a.png": a, "/data/maps/b.png": b}, PAGE)
    page = Page(text)
    assert page.open == []  # every element closed
    cards = page.tags("article", **{"class": "card"})
    assert [c["class"] for c in cards] == ["card failed", "card built", "card skipped"]
    plain = " ".join(page.text)
    for shown in ("12,345 mapped", "400 x 200 cells, 20.0 x 10.0 m", "took 2.2 s",
                  "3 columns left out", "2026-12-02 06:59:00 UTC", "checked in 0.0 s",
                  "/data/logs/c.bag: byte 3000: bad CRC", "up to date", "gridmap batch: 3 logs",
                  "1 built", "1 up to date", "1 failed", "pose odometry", "in 12.5 s"):  # fmt: skip
        assert shown in plain, shown
    # the summary links the failure to its card
    assert page.tags("a", href="#log-1") and cards[0]["id"] == "log-1"
    # thumbnails are the given PNGs, inline; a failed log has none
    images = page.tags("img")
    assert [base64.b64decode(str(i["src"]).split(",", 1)[1]) for i in images] == [a, b]
    assert [(i["width"], i["height"]) for i in images] == [("40", "20"), ("10", "20")]
    hrefs = [str(x["href"]) for x in page.tags("a")]
    assert {"a.png", "a.yaml", "b.png", "b.yaml", "batch-report.jsonl"} <= set(hrefs)
    assert "c.png" not in hrefs and "c.yaml" not in hrefs


def test_nothing_is_fetched_from_anywhere() -> None:
    text = overview_html(records(), {"/data/maps/a.png": thumb(4, 4)}, PAGE)
    page = Page(text)
    for tag, attrs in page.attrs:
        for name in ("src", "href"):
            value = attrs.get(name)
            if value is None:
                continue
            assert value.startswith(("data:image/png;base64,", "#")) or not re.match(
                r"^([a-z][a-z0-9+.-]*:|/)", value
            ), (tag, value)
    assert "<script" not in text and "<link" not in text and "@import" not in text
    assert "url(" not in text


def test_names_and_messages_are_escaped_and_links_encoded() -> None:
    nasty = '/data/logs/<script>alert("x")</script> & #1.csv'
    record = {"log": nasty, "map": "/data/maps/<script>alert(\"x\")</script> & #1.png",
              "status": "failed", "error": "bad <b>bold</b> & 'quoted'", "seconds": {}}  # fmt: skip
    text = overview_html([record], {}, PAGE)
    assert "<script>" not in text and "<b>" not in text
    page = Page(text)
    plain = "".join(page.text)
    assert '<script>alert("x")</script> & #1.csv' in plain
    assert "bad <b>bold</b> & 'quoted'" in plain
    page_ok = overview_html(
        [{**record, "status": "built", "error": None}], {}, PAGE
    )  # fmt: skip
    hrefs = [str(a["href"]) for a in Page(page_ok).tags("a")]
    assert "%3Cscript%3Ealert%28%22x%22%29%3C/script%3E%20%26%20%231.png" in hrefs


def test_an_interrupted_run_says_so_and_lists_what_did_not_finish() -> None:
    page = OverviewPage(**{**PAGE.__dict__, "total": 5, "interrupted": True,
                           "pending": ("/data/logs/d.csv", "/data/logs/e&f.csv")})  # fmt: skip
    text = overview_html(records(), {}, page)
    plain = " ".join(Page(text).text)
    assert "Interrupted (Ctrl-C) after 3 of 5 logs" in plain
    assert "Not finished (2)" in plain and "/data/logs/e&f.csv" in plain
    assert "<title>gridmap batch: 5 logs, interrupted</title>" in text


def test_a_report_elsewhere_is_linked_relative_to_the_page() -> None:
    page = OverviewPage(**{**PAGE.__dict__, "report": "/data/reports/nightly.jsonl"})
    hrefs = [str(a["href"]) for a in Page(overview_html(records(), {}, page)).tags("a")]
    assert "../reports/nightly.jsonl" in hrefs


def test_png_size_reads_the_header_and_refuses_other_bytes() -> None:
    assert png_size(thumb(7, 3)) == (7, 3)
    assert png_size(b"GIF89a" + bytes(30)) is None and png_size(b"") is None


def test_a_thumbnail_keeps_a_one_cell_wall_and_the_map_upright() -> None:
    prob = np.full((1000, 500), 0.1)  # free, 1000 rows tall
    prob[:, 250] = 0.9  # a wall one cell wide, along the map
    prob[:100, :] = np.nan  # the bottom 100 rows unknown
    pixels = thumbnail_pixels(prob, 0.65, 0.25, size_px=100)
    assert pixels.shape == (100, 50)  # 10 x 10 cells to a pixel
    assert (pixels[:90, 25] == 0).all()  # the wall survives
    assert (pixels[-10:, :25] == 205).all()  # unknown at the bottom of the picture
    assert (pixels[:90, :25] == 254).all()
    speckled = np.full((1000, 500), 0.1)
    speckled[500, 100] = 0.9  # one stray occupied cell does not blacken its block
    assert (thumbnail_pixels(speckled, 0.65, 0.25, size_px=100) == 254).all()
    decoded = np.asarray(Image.open(io.BytesIO(thumbnail_png(prob, 0.65, 0.25, 100))))
    assert (decoded == pixels).all()


def test_a_small_map_keeps_a_pixel_per_cell_and_a_ragged_edge_is_pooled() -> None:
    prob = np.full((3, 5), np.nan)
    prob[0, 0] = 0.9
    assert thumbnail_pixels(prob, 0.65, 0.25).shape == (3, 5)
    ragged = np.full((7, 5), 0.1)
    ragged[6, 4] = 0.9  # top right corner, in a block of its own
    pixels = thumbnail_pixels(ragged, 0.65, 0.25, size_px=3)
    assert pixels.shape == (3, 2) and pixels[0, 1] == 0 and (pixels[1:, :] == 254).all()
