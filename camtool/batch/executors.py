"""Where the jobs of a batch run: a local pool, or a Dask distributed cluster.

Both run the same unit of work, ``runner.run_one`` (one ``camtool run``
process per job), so the programs are the same whichever executor ran them.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor, as_completed

from ..errors import BadInput
from .runner import JobResult, JobSpec, kill_running, run_one


def get_executor(name: str, workers: int, scheduler: str | None = None):
    """The executor called ``name`` (local or dask) with ``workers`` parallel jobs."""
    if name == "local":
        if scheduler:
            raise BadInput("--scheduler works only with --executor dask")
        return LocalExecutor(workers)
    if name == "dask":
        return DaskExecutor(workers, scheduler)
    raise BadInput(f"--executor {name!r}: expected local or dask")


class LocalExecutor:
    """At most ``workers`` jobs at once on this machine.

    Each job already is its own process (``run_one``), so the pool only has to
    wait on them: a thread per slot, which keeps kill-on-timeout and crash
    isolation in the job process and costs no extra interpreter start-up.
    """

    def __init__(self, workers: int):
        self.workers = max(1, int(workers))

    def run(self, specs: list[JobSpec], on_start=None, on_done=None) -> list[JobResult]:
        def task(spec):
            if on_start:
                on_start(spec)
            return run_one(spec)

        results = []
        pool = ThreadPoolExecutor(max_workers=self.workers, thread_name_prefix="camtool-batch")
        try:
            futures = [pool.submit(task, s) for s in specs]
            for fut in as_completed(futures):
                results.append(fut.result())
                if on_done:
                    on_done(results[-1])
        except BaseException:  # e.g. Ctrl-C: no job may outlive the batch
            pool.shutdown(wait=False, cancel_futures=True)
            kill_running()
            raise
        pool.shutdown(wait=True)
        return results


class DaskExecutor:
    """The jobs as Dask tasks: on the cluster at ``scheduler`` (tcp://host:port),
    or on a LocalCluster of ``workers`` single-threaded worker processes bound to
    127.0.0.1. Job and output paths must be the same on every worker (shared disk).
    """

    def __init__(self, workers: int, scheduler: str | None = None):
        try:
            import distributed  # noqa: F401
        except ImportError:
            raise BadInput("--executor dask needs Dask distributed: pip install 'camtool[dask]'") from None
        self.workers = max(1, int(workers))
        self.scheduler = scheduler

    def _client(self):
        from distributed import Client, LocalCluster

        if self.scheduler:
            try:
                return Client(self.scheduler, timeout="10s"), None
            except (OSError, TimeoutError, ValueError) as exc:
                raise BadInput(f"--scheduler {self.scheduler}: cannot reach the Dask scheduler ({exc})") from None
        cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None, silence_logs=40)
        return Client(cluster), cluster

    def run(self, specs: list[JobSpec], on_start=None, on_done=None) -> list[JobResult]:
        from distributed import as_completed as dask_completed

        client, cluster = self._client()
        try:
            futures = {}
            for s in specs:
                fut = client.submit(run_one, s, pure=False, key=f"camtool-batch-{s.name}-{id(s):x}")
                futures[fut] = s
                if on_start:
                    on_start(s)
            results = []
            for fut in dask_completed(list(futures)):
                try:
                    r = fut.result()
                except Exception as exc:  # the worker running it died, or the task was lost
                    s = futures[fut]
                    r = JobResult(job=s.job, name=s.name, outdir=s.outdir, status="failed", exit_code=1,
                                  reason=f"dask: {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}")
                results.append(r)
                if on_done:
                    on_done(r)
            return results
        finally:
            client.close()
            if cluster is not None:
                cluster.close()


# ---------------------------------------------------------------- the batch

def run_batch(specs, executor: str = "local", workers: int | None = None, scheduler: str | None = None,
              on_start=None, on_done=None) -> list[JobResult]:
    """Run ``specs`` on the ``local`` pool or on ``dask``; results sorted by job path.

    ``on_start(spec)`` and ``on_done(result)`` report progress (called from
    worker threads for the local pool).
    """
    workers = workers or os.cpu_count() or 1
    results = get_executor(executor, workers, scheduler).run(list(specs), on_start, on_done) if specs else []
    return sorted(results, key=lambda r: r.job)
