"""Where batch jobs run: in this process, in local processes, or on a Dask cluster.

Each executor is a function from jobs to their results, in the order they finish; the jobs and
results are plain picklable dataclasses and :func:`~gridmap_cli.runs.batch.run_job` needs nothing
but its job, so a map is the same bytes wherever it was built.

Dask (``distributed``) is an optional extra: ``pip install 'gridmap-cli[dask]'``.
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import threading
import time
from collections.abc import Callable, Generator, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import TYPE_CHECKING, Any

from gridmap_cli.errors import GridmapError, UsageError
from gridmap_cli.runs.fuse import (
    FuseJob,
    Partial,
    canonical,
    check_distinct,
    combine,
    partial_of,
    reduce_tree,
    tree_pairs,
)

if TYPE_CHECKING:  # batch (hashlib, its job bookkeeping) loads only when a batch runs
    from gridmap_cli.runs.batch import Job, JobResult

EXECUTORS = ("local", "dask")
DASK_INSTALL = "pip install 'gridmap-cli[dask]'"
#: How long to wait for the Dask scheduler before giving up (a Dask duration).
DASK_CONNECT_TIMEOUT = "10s"

#: How long workers get to unwind after Ctrl-C (their temporary files deleted) before they
#: are killed.
STOP_GRACE_S = 5.0
#: Dask's schemes for a scheduler a client can reach.
DASK_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")
_ADDRESS = re.compile(
    r"(?:(?P<scheme>[A-Za-z][A-Za-z0-9+.-]*)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[^\s:/\[\]]+)"
    r":(?P<port>[0-9]{1,5})"
)

#: An executor: the jobs in, their results out as they finish; closing the generator early
#: (Ctrl-C) stops the jobs still running.
Submit = Callable[[Sequence["Job"]], Generator["JobResult", None, None]]


def lost(job: Job, exc: BaseException) -> JobResult:
    """The result of a job whose process died before it could report (run_job never raises):
    failed, so the batch goes on and the report says so."""
    from gridmap_cli.runs.batch import JobResult

    return JobResult(
        log=str(job.log),
        map=str(job.output),
        status="failed",
        error=f"{job.log}: the worker building it died ({type(exc).__name__}: {exc}); out of "
        "memory, or killed?",
    )


def inline(jobs: Sequence[Job]) -> Generator[JobResult, None, None]:
    """Run the jobs one after the other in this process."""
    from gridmap_cli.runs.batch import run_job

    for job in jobs:
        yield run_job(job)


def local_processes(workers: int) -> Submit:
    """Run the jobs on ``workers`` local processes (one job each at a time)."""

    def submit(jobs: Sequence[Job]) -> Generator[JobResult, None, None]:
        if workers <= 1 or len(jobs) <= 1:
            yield from inline(jobs)
            return
        from gridmap_cli.runs.batch import run_job

        pool = ProcessPoolExecutor(max_workers=min(workers, len(jobs)), initializer=_worker_start)
        futures: dict[Future[JobResult], Job] = {}
        finished = False
        try:
            with _ctrl_c_as_flag() as stopped:
                futures = {pool.submit(_in_worker, run_job, job): job for job in jobs}
                pending: set[Future[JobResult]] = set(futures)
                while pending:
                    done, pending = wait(pending, timeout=0.1, return_when=FIRST_COMPLETED)
                    for future in done:
                        try:
                            yield future.result()
                        except Exception as exc:  # the worker died (killed, out of memory)
                            yield lost(futures[future], exc)
                    if stopped.is_set():
                        raise KeyboardInterrupt
            finished = True
        finally:
            if not finished:  # Ctrl-C, or the caller stopped reading: end the jobs too
                stop_workers(pool)
            pool.shutdown(wait=True)

    return submit


@contextlib.contextmanager
def _ctrl_c_as_flag() -> Iterator[threading.Event]:
    """Ctrl-C sets the flag this yields instead of raising wherever the main thread is. Raised
    inside the pool's own waiting (between the locks of its futures), KeyboardInterrupt can leave
    a future's lock held, and the pool's manager thread, which must take it to report a result,
    then waits for ever, and so does the shutdown that joins it. Off the main thread (the
    Python API run from a thread) signals cannot be handled, and the flag never sets."""
    stopped = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield stopped
        return
    previous = signal.signal(signal.SIGINT, lambda signum, frame: stopped.set())
    try:
        yield stopped
    finally:
        signal.signal(signal.SIGINT, previous)


#: True in a worker process while it runs a job (what Ctrl-C does there depends on it).
_in_job = False


def _worker_start() -> None:
    """A local worker's start: Ctrl-C interrupts the job it runs (the job unwinds and deletes
    its temporary files), and ends an idle worker quietly (Python would print a traceback)."""
    signal.signal(signal.SIGINT, _interrupted)


def _interrupted(signum: int, frame: object) -> None:
    if _in_job:
        raise KeyboardInterrupt
    os._exit(128 + signum)


def _in_worker(run: Callable[[Job], JobResult], job: Job) -> JobResult:
    global _in_job
    _in_job = True
    try:
        return run(job)
    finally:
        _in_job = False


def stop_workers(pool: ProcessPoolExecutor) -> None:
    """End a pool's jobs now: the queued ones are cancelled, the running ones interrupted as
    Ctrl-C would (each unwinds and deletes its temporary files), and a worker still alive after
    :data:`STOP_GRACE_S` is killed (what it leaves, a later run deletes)."""
    # the pool has no public way to end running work before Python 3.14; shutdown drops it
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    deadline = time.monotonic() + STOP_GRACE_S
    while alive := [p for p in processes if p.is_alive()]:
        for process in alive:  # the Ctrl-C of a terminal reached them too: give it a moment
            process.join(0.5 / len(alive))
        alive = [p for p in alive if p.is_alive()]
        if alive and time.monotonic() > deadline:
            for process in alive:
                process.kill()
                process.join(STOP_GRACE_S)
            return
        for process in alive:  # again: a worker may have taken a job queued for it
            with contextlib.suppress(OSError):
                os.kill(process.pid, signal.SIGINT)


def check_scheduler(address: str) -> None:
    """Refuse a ``--scheduler`` that is no Dask address (``[tcp://]HOST:PORT``) before any
    work, with a usage error."""
    match = _ADDRESS.fullmatch(address.strip())
    scheme = (match.group("scheme") or "tcp").lower() if match else ""
    if match is None or scheme not in DASK_SCHEMES or not 0 < int(match.group("port")) < 65536:
        raise UsageError(
            f"--scheduler {address!r} is not a Dask scheduler address: give tcp://HOST:PORT "
            f"(e.g. tcp://scheduler:8786; schemes {', '.join(DASK_SCHEMES)})"
        )


def dask_client(address: str) -> Any:
    """A ``distributed.Client`` connected to the scheduler at ``address``.

    Raises :class:`UsageError` saying how to install the extra when ``distributed`` is
    missing or when ``address`` is no scheduler address, and :class:`GridmapError` when the
    scheduler cannot be reached.
    """
    check_scheduler(address)
    try:
        from distributed import Client
    except ImportError:
        raise UsageError(
            f"--executor dask needs the Dask extra, which is not installed: {DASK_INSTALL}"
        ) from None
    try:
        return Client(address, timeout=DASK_CONNECT_TIMEOUT)  # type: ignore[no-untyped-call]
    except (OSError, TimeoutError) as exc:
        raise GridmapError(f"cannot reach the Dask scheduler at {address}: {exc}") from exc
    except ValueError as exc:  # an address Dask's own parser refuses
        raise UsageError(f"--scheduler {address!r}: {exc}") from exc


def check_dask() -> None:
    """Refuse ``--executor dask`` before any work when the extra is not installed."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise UsageError(
            f"--executor dask needs the Dask extra, which is not installed: {DASK_INSTALL}"
        ) from None


@contextlib.contextmanager
def dask_cluster(address: str) -> Iterator[Submit]:
    """Run the jobs as tasks on the Dask cluster whose scheduler is at ``address``
    (``tcp://host:8786``), connected on entry (so an unreachable one stops a run before it
    writes anything) and closed on exit. Workers must see the logs and the output folder at the
    same paths (a shared file system), as every job reads and writes by path. Ctrl-C cancels
    the tasks; one already running on a worker runs to its end (Dask does not interrupt a
    task), writing its map whole."""
    client = dask_client(address)
    try:

        def submit(jobs: Sequence[Job]) -> Generator[JobResult, None, None]:
            from distributed import as_completed as dask_completed

            from gridmap_cli.runs.batch import run_job

            futures = client.map(run_job, list(jobs), pure=False)
            finished = False
            try:
                job_of = {future.key: job for future, job in zip(futures, jobs, strict=True)}
                for future in dask_completed(futures):  # type: ignore[no-untyped-call]
                    try:
                        yield future.result()
                    except Exception as exc:  # a worker died (KilledWorker) or lost the task
                        yield lost(job_of[future.key], exc)
                finished = True
            finally:
                if not finished:
                    with contextlib.suppress(Exception):
                        client.cancel(futures)

        yield submit
    finally:
        client.close()


# ------------------------------------------------------------------------------ fused builds


def fuse_local(jobs: Sequence[FuseJob], workers: int = 1) -> Partial:
    """Partial grids of the logs on ``workers`` local processes, added as a tree here."""
    if workers <= 1 or len(jobs) <= 1:
        partials = [partial_of(job) for job in jobs]
    else:
        with ProcessPoolExecutor(max_workers=min(workers, len(jobs))) as pool:
            partials = list(pool.map(partial_of, jobs))
    return reduce_tree(canonical(partials))


def _keys_of(partial: Partial) -> tuple[str, ...]:
    return partial.keys


def fuse_dask(jobs: Sequence[FuseJob], address: str) -> Partial:
    """Partial grids of the logs as tasks on the Dask cluster at ``address``, added pairwise as
    a tree of tasks on its workers (the same tree, in the same order, as :func:`fuse_local`);
    only the fused grid comes back."""
    client = dask_client(address)
    try:
        futures = client.map(partial_of, list(jobs), pure=False)
        keys = client.gather(client.map(_keys_of, futures, pure=False))
        check_distinct(keys)
        level = [f for _, f in sorted(zip(keys, futures, strict=True), key=lambda kf: kf[0])]
        for pairs in tree_pairs(len(level)):
            merged = [client.submit(combine, level[i], level[j], pure=False) for i, j in pairs]
            if len(level) % 2:
                merged.append(level[-1])
            level = merged
        total: Partial = level[0].result()
        return total
    finally:
        client.close()
