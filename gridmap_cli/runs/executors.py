"""Where batch jobs run: in this process, in local processes, or on a Dask cluster.

Each executor is a function from jobs to their results, in the order they finish; the jobs and
results are plain picklable dataclasses and :func:`~gridmap_cli.runs.batch.run_job` needs nothing
but its job, so a map is the same bytes wherever it was built.

Dask (``distributed``) is an optional extra: ``pip install 'gridmap-cli[dask]'``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
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

Submit = Callable[[Sequence["Job"]], Iterator["JobResult"]]


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


def inline(jobs: Sequence[Job]) -> Iterator[JobResult]:
    """Run the jobs one after the other in this process."""
    from gridmap_cli.runs.batch import run_job

    for job in jobs:
        yield run_job(job)


def local_processes(workers: int) -> Submit:
    """Run the jobs on ``workers`` local processes (one job each at a time)."""

    def submit(jobs: Sequence[Job]) -> Iterator[JobResult]:
        if workers <= 1 or len(jobs) <= 1:
            yield from inline(jobs)
            return
        from gridmap_cli.runs.batch import run_job

        with ProcessPoolExecutor(max_workers=min(workers, len(jobs))) as pool:
            futures = {pool.submit(run_job, job): job for job in jobs}
            for future in as_completed(futures):
                try:
                    yield future.result()
                except Exception as exc:  # the worker died (killed, out of memory)
                    yield lost(futures[future], exc)

    return submit


def dask_client(address: str) -> Any:
    """A ``distributed.Client`` connected to the scheduler at ``address``.

    Raises :class:`UsageError` saying how to install the extra when ``distributed`` is
    missing, and :class:`GridmapError` when the scheduler cannot be reached.
    """
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


def check_dask() -> None:
    """Refuse ``--executor dask`` before any work when the extra is not installed."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise UsageError(
            f"--executor dask needs the Dask extra, which is not installed: {DASK_INSTALL}"
        ) from None


def dask_cluster(address: str) -> Submit:
    """Run the jobs as tasks on the Dask cluster whose scheduler is at ``address``
    (``tcp://host:8786``). Workers must see the logs and the output folder at the same paths
    (a shared file system), as every job reads and writes by path."""

    def submit(jobs: Sequence[Job]) -> Iterator[JobResult]:
        from distributed import as_completed as dask_completed

        from gridmap_cli.runs.batch import run_job

        client = dask_client(address)
        try:
            futures = client.map(run_job, list(jobs), pure=False)
            job_of = {future.key: job for future, job in zip(futures, jobs, strict=True)}
            for future in dask_completed(futures):  # type: ignore[no-untyped-call]
                try:
                    yield future.result()
                except Exception as exc:  # a worker died (KilledWorker) or lost the task
                    yield lost(job_of[future.key], exc)
        finally:
            client.close()

    return submit


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
