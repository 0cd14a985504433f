"""Progress on a terminal for the stages of a command that can take a while: reading the log,
scan matching, loop closures (mapping has its bar in :func:`~gridmap_cli.cli.common.progress_bar`).

Nothing is shown when stderr is not a terminal (pipelines, cron, CI logs) or with ``--quiet``,
and a stage over in less than :data:`SHOW_AFTER_S` shows nothing either. The libraries never
print: they take a callback (``progress(stage, done, total)`` for scan matching and SLAM), which
:class:`StageBars` turns into one bar per stage. Readers report nothing while they read, so the
reading stage shows how long it has been reading (:func:`reading`).
"""

from __future__ import annotations

import contextlib
import sys
import threading
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from tqdm import tqdm

#: A stage shows a bar only once it has run this long (tqdm's ``delay``).
SHOW_AFTER_S = 1.0
#: How often the reading stage's elapsed time is redrawn.
TICK_S = 0.25
#: What the libraries' stages count.
STAGE_UNITS = {"scan matching": " scans", "loop closures": " rounds"}


def on_terminal(quiet: bool) -> bool:
    """True when progress may be drawn: stderr is a terminal and ``--quiet`` was not given."""
    return not quiet and sys.stderr.isatty()


def _bar(desc: str, total: int | None, unit: str, **extra: Any) -> tqdm[Any]:
    from tqdm import tqdm

    return tqdm(
        total=total, desc=desc, unit=unit, file=sys.stderr, leave=False, delay=SHOW_AFTER_S,
        dynamic_ncols=True, **extra,
    )  # fmt: skip


@contextlib.contextmanager
def reading(what: str, quiet: bool) -> Iterator[None]:
    """While the body reads ``what``: "reading NAME: 12s" on a terminal, redrawn every
    :data:`TICK_S` by a thread (the readers give no count to show)."""
    if not on_terminal(quiet):
        yield
        return
    bar = _bar(f"reading {what}", None, "", bar_format="{desc}: {elapsed}")
    done = threading.Event()

    def tick() -> None:  # a read over within SHOW_AFTER_S draws nothing
        if done.wait(SHOW_AFTER_S):
            return
        while not done.wait(TICK_S):
            bar.refresh()

    thread = threading.Thread(target=tick, name="gridmap-reading", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        bar.close()


class StageBars:
    """A ``progress(stage, done, total)`` callback drawing one bar per stage: a new stage
    closes the last one's bar. Draws nothing off a terminal (see :func:`on_terminal`)."""

    def __init__(self, quiet: bool) -> None:
        self.shown = on_terminal(quiet)
        self.stage: str | None = None
        self.bar: tqdm[Any] | None = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if not self.shown:
            return
        if stage != self.stage or self.bar is None:
            self.close()
            self.stage = stage
            self.bar = _bar(stage, total, STAGE_UNITS.get(stage, ""))
        if total != self.bar.total:
            self.bar.total = total
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def __enter__(self) -> StageBars:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
