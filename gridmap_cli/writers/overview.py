"""Batch's overview page (``OUTDIR/index.html``): one card per log, a summary on top.

A pure function from the report's records (what ``batch-report.jsonl`` holds, one mapping per
log) and the maps' thumbnails (PNG bytes) to the text of one HTML file. Everything it shows is
in that file: styles inline, thumbnails as ``data:`` URIs, links relative to the page's folder,
no script, no font, no request to anywhere, so it opens from ``file://`` and from any static
web server alike. Every name and message from a log is HTML-escaped; every link is
percent-encoded.
"""

from __future__ import annotations

import base64
import html
import os
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import quote

#: What a record's status is called on the page.
STATUS_WORDS = {"built": "built", "skipped": "up to date", "failed": "failed"}
#: Thumbnails whose longer side is below this are scaled up as blocks (image-rendering pixelated).
SHARP_BELOW_PX = 200
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@dataclass(frozen=True)
class OverviewPage:
    """What the page says besides the records.

    ``folder``: the page's folder (links are relative to it); ``report``: the JSON-lines
    report's path; ``generated``: when the run ended, as shown (UTC); ``seconds``: the run's
    wall time; ``resolution_m``: the maps' cell size; ``options``: the build options worth
    showing, as (name, value) pairs; ``total``: the run's logs (more than the records when it
    was interrupted); ``pending``: the logs of an interrupted run that did not finish.
    """

    folder: str
    report: str
    generated: str
    seconds: float
    resolution_m: float
    version: str
    total: int
    options: tuple[tuple[str, str], ...] = ()
    interrupted: bool = False
    pending: tuple[str, ...] = field(default=())


def png_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) of PNG bytes from their header, or None if they are not a PNG."""
    if len(data) < 24 or not data.startswith(_PNG_SIGNATURE) or data[12:16] != b"IHDR":
        return None
    width, height = struct.unpack(">II", data[16:24])
    return width, height


def overview_html(
    records: Sequence[Mapping[str, Any]], thumbnails: Mapping[str, bytes], page: OverviewPage
) -> str:
    """The overview page of a batch run.

    ``records``: one per finished log, as the report holds them (``log``, ``map``, ``status``,
    ``error``, ``seconds``, ``cells``, ``readings``, ``warnings``, ``built_at``);
    ``thumbnails``: PNG bytes by a record's ``map``. Failed logs come first, then the others
    in the order given.
    """
    ordered = [r for r in records if r.get("status") == "failed"]
    ordered += [r for r in records if r.get("status") != "failed"]
    cards = "\n".join(
        _card(record, thumbnails.get(str(record.get("map"))), page, number)
        for number, record in enumerate(ordered, 1)
    )
    pending = "".join(f"<li>{_text(log)}</li>" for log in page.pending)
    pending_block = (
        f'<section class="pending"><h2>Not finished ({len(page.pending)})</h2>'
        f"<ul>{pending}</ul></section>"
        if pending
        else ""
    )
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{_text(_title(records, page))}</title>\n"
        f"<style>{_STYLE}</style>\n</head>\n<body>\n"
        f"{_summary(records, ordered, page)}\n"
        f'<main class="cards">\n{cards}\n</main>\n{pending_block}\n'
        "</body>\n</html>\n"
    )


def _title(records: Sequence[Mapping[str, Any]], page: OverviewPage) -> str:
    failed = sum(1 for r in records if r.get("status") == "failed")
    state = f"{failed} failed" if failed else "all mapped"
    if page.interrupted:
        state = "interrupted"
    return f"gridmap batch: {page.total} logs, {state}"


def _summary(
    records: Sequence[Mapping[str, Any]],
    ordered: Sequence[Mapping[str, Any]],
    page: OverviewPage,
) -> str:
    counts = {status: sum(1 for r in records if r.get("status") == status) for status in
              STATUS_WORDS}  # fmt: skip
    badges = " ".join(
        f'<span class="badge {status}">{counts[status]:,} {word}</span>'
        for status, word in STATUS_WORDS.items()
    )
    notice = ""
    if page.interrupted:
        notice = (
            f'<p class="notice">Interrupted (Ctrl-C) after {len(records):,} of {page.total:,} '
            "logs: the maps of the others were left as they were.</p>"
        )
    failed_links = "".join(
        f'<li><a href="#log-{n}">{_text(_name(r))}</a>: {_text(r.get("error") or "")}</li>'
        for n, r in enumerate(ordered, 1)
        if r.get("status") == "failed"
    )
    failed_block = f'<ul class="failures">{failed_links}</ul>' if failed_links else ""
    options = " · ".join(f"{_text(k)} {_text(v)}" for k, v in page.options)
    report = _href(page.report, page.folder)
    return (
        f'<header>\n<h1>gridmap batch: {page.total:,} logs</h1>\n<p class="counts">{badges}</p>\n'
        f"{notice}{failed_block}"
        f'<p class="meta">Run ended {_text(page.generated)} in {page.seconds:.1f} s · maps in '
        f'<code>{_text(page.folder)}</code> · <a href="{report}">report</a> · gridmap '
        f"{_text(page.version)}</p>\n"
        + (f'<p class="meta">{options}</p>\n' if options else "")
        + "</header>"
    )


def _card(
    record: Mapping[str, Any], thumbnail: bytes | None, page: OverviewPage, number: int
) -> str:
    status = str(record.get("status", ""))
    word = STATUS_WORDS.get(status, status)
    map_path = str(record.get("map", ""))
    image, yaml_file = _href(map_path, page.folder), _href(_yaml_of(map_path), page.folder)
    size = png_size(thumbnail) if thumbnail else None
    if status != "failed" and thumbnail and size:
        source = "data:image/png;base64," + base64.b64encode(thumbnail).decode("ascii")
        # a map of few cells is drawn in blocks, not blurred; a shrunk one is smoothed
        sharp = ' class="cells"' if max(size) < SHARP_BELOW_PX else ""
        picture = (
            f'<a class="thumb" href="{image}"><img{sharp} src="{source}" width="{size[0]}" '
            f'height="{size[1]}" alt="map of {_text(_name(record))}"></a>'
        )
    else:
        picture = (
            f'<div class="thumb none">{"no map" if status == "failed" else "no preview"}</div>'
        )
    facts = []
    readings = record.get("readings")
    if status != "failed" and isinstance(readings, int):
        facts.append(("readings", f"{readings:,} mapped"))
    cells = record.get("cells") or {}
    if isinstance(cells, Mapping) and cells.get("width") and cells.get("height"):
        w, h = int(cells["width"]), int(cells["height"])
        metres = f"{w * page.resolution_m:.1f} x {h * page.resolution_m:.1f} m"
        facts.append(("map", f"{w:,} x {h:,} cells, {metres}"))
    seconds = record.get("seconds") or {}
    if isinstance(seconds, Mapping) and "total" in seconds:
        verb = "checked in" if status == "skipped" else "took"
        facts.append(("time", f"{verb} {float(seconds['total']):.1f} s"))
    quality = quality_text(record.get("quality"))
    if quality:
        facts.append(("quality", quality))
    if record.get("built_at"):
        facts.append(("built", str(record["built_at"]).replace("T", " ").replace("Z", " UTC")))
    facts_html = "".join(f"<dt>{_text(k)}</dt><dd>{_text(v)}</dd>" for k, v in facts)
    warnings = "".join(f"<li>{_text(w)}</li>" for w in record.get("warnings") or ())
    links = [f'<a href="{image}">image</a>', f'<a href="{yaml_file}">YAML</a>']
    if status == "failed":
        links = []
    links.append(f'<a href="{_href(page.report, page.folder)}">report</a>')
    return (
        f'<article class="card {_text(status)}" id="log-{number}">\n{picture}\n'
        f'<div class="body">\n<h2><span class="name">{_text(_name(record))}</span> '
        f'<span class="badge {_text(status)}">{_text(word)}</span></h2>\n'
        f'<p class="path">{_text(record.get("log", ""))}</p>\n'
        + (f"<dl>{facts_html}</dl>\n" if facts_html else "")
        + (f'<ul class="warnings">{warnings}</ul>\n' if warnings else "")
        + (f'<p class="error">{_text(record["error"])}</p>\n' if record.get("error") else "")
        + f"<nav>{' '.join(links)}</nav>\n</div>\n</article>"
    )


def quality_text(quality: object) -> str:
    """A map's quality block (docs/quality.md) in a few words; empty when it says nothing."""
    if not isinstance(quality, Mapping):
        return ""
    parts = []
    spread = quality.get("spread")
    if isinstance(spread, Mapping) and isinstance(spread.get("share_within_m"), Mapping):
        shares = spread["share_within_m"]
        parts.append(
            "pose spread within "
            + ", ".join(f"{k} m: {100 * float(v):.0f} %" for k, v in shares.items())
        )
    echoes = quality.get("echo_consistency")
    if isinstance(echoes, Mapping) and echoes.get("in_free") is not None:
        parts.append(f"{100 * float(echoes['in_free']):.1f} % of laser echoes in free cells")
    revisits = quality.get("revisits")
    if isinstance(revisits, Mapping) and revisits.get("mean_m") is not None:
        parts.append(
            f"revisits {float(revisits['mean_m']):.2f} m apart (mean of {revisits['relations']})"
        )
    closures = quality.get("closures")
    if isinstance(closures, Mapping) and closures.get("median_nees") is not None:
        parts.append(
            f"{closures['closures']} closures, median NEES {float(closures['median_nees']):.2f}"
        )
    return "; ".join(parts)


def _name(record: Mapping[str, Any]) -> str:
    return os.path.basename(str(record.get("log", "")).rstrip("/")) or "?"


def _yaml_of(map_path: str) -> str:
    root, _ = os.path.splitext(map_path)
    return root + ".yaml"


def _href(path: str, folder: str) -> str:
    """``path`` as a link from ``folder``: relative, percent-encoded, HTML-escaped."""
    relative = os.path.relpath(path, folder) if os.path.isabs(path) else path
    return html.escape(quote(relative.replace(os.sep, "/")), quote=True)


def _text(value: object) -> str:
    return html.escape(str(value), quote=True)


_STYLE = """
:root { color-scheme: light; --ink: #1f2328; --muted: #59636e; --line: #d1d9e0;
  --built: #1a7f37; --skipped: #4d6a88; --failed: #cf222e; }
* { box-sizing: border-box; }
body { margin: 0; padding: 24px; font: 14px/1.45 system-ui, -apple-system, "Segoe UI",
  sans-serif; color: var(--ink); background: #f6f8fa; }
header { margin-bottom: 20px; }
h1 { font-size: 22px; margin: 0 0 8px; }
.counts { margin: 0 0 8px; }
.badge { display: inline-block; padding: 1px 8px; border-radius: 10px; font-size: 12px;
  font-weight: 600; color: #fff; background: var(--muted); white-space: nowrap; }
.badge.built { background: var(--built); }
.badge.skipped { background: var(--skipped); }
.badge.failed { background: var(--failed); }
.meta { color: var(--muted); margin: 4px 0; }
.notice { background: #fff8c5; border: 1px solid #d4a72c; padding: 6px 10px; border-radius: 6px; }
.failures { margin: 6px 0; padding-left: 20px; color: var(--failed); }
.failures a { color: inherit; font-weight: 600; }
.cards { display: grid; grid-template-columns: repeat(auto-fill, minmax(320px, 1fr));
  gap: 16px; }
.card { background: #fff; border: 1px solid var(--line); border-top: 4px solid var(--muted);
  border-radius: 8px; overflow: hidden; display: flex; flex-direction: column; }
.card.built { border-top-color: var(--built); }
.card.skipped { border-top-color: var(--skipped); }
.card.failed { border-top-color: var(--failed); }
.thumb { display: flex; align-items: center; justify-content: center; height: 240px;
  background: #cdcdcd; }
.thumb img { width: 100%; height: 100%; object-fit: contain; }
.thumb img.cells { image-rendering: pixelated; }
.thumb.none { color: var(--muted); background: repeating-linear-gradient(45deg, #eee 0 10px,
  #f6f6f6 10px 20px); }
.body { padding: 10px 14px 12px; }
h2 { font-size: 15px; margin: 0 0 2px; display: flex; gap: 8px; align-items: baseline;
  justify-content: space-between; }
.name { overflow-wrap: anywhere; }
.path { color: var(--muted); font-size: 12px; margin: 0 0 8px; overflow-wrap: anywhere; }
dl { display: grid; grid-template-columns: auto 1fr; gap: 2px 10px; margin: 0 0 8px; }
dt { color: var(--muted); }
dd { margin: 0; }
.warnings { margin: 0 0 8px; padding: 6px 10px 6px 26px; background: #fff8c5;
  border-radius: 6px; font-size: 13px; }
.error { margin: 0 0 8px; padding: 6px 10px; background: #ffebe9; color: #82071e;
  border-radius: 6px; font-size: 13px; overflow-wrap: anywhere; }
nav a { margin-right: 12px; }
.pending { margin-top: 20px; color: var(--muted); }
code { font-size: 13px; }
"""
