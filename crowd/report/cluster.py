"""Where the work of ``crowd report`` and ``crowd build`` runs (:class:`ClusterPool`): dask.distributed or this
process.

Scale-out (``--cluster``): by default the work runs on an
embedded dask ``LocalCluster`` on loopback (one single-threaded worker process
per core); ``--cluster tcp://HOST:PORT`` uses a running dask scheduler and
``--cluster none`` keeps everything in this process, serially. Timed runs come
first, through one queue per host: a host runs one timed run at a time and
nothing else of the report runs anywhere meanwhile, so no two timed runs share a
machine's cores and no image-error work disturbs them; different hosts time in
parallel. Then the true references (crowd.reference) and the image error of every sampled
frame run in parallel on all workers. A run (:func:`crowd.report.runs.run_task`) writes to a
temporary folder on its worker and returns its files as data; the client writes
them into the report. Results are the same as in this process (same frames,
same counts, same image errors; only the wall-clock times differ).
"""
from __future__ import annotations

from crowd.errors import CrowdError

#: default ``--cluster``: an embedded dask LocalCluster on loopback
DEFAULT_CLUSTER = "local"
#: ``--cluster`` value that runs everything in this process, serially
NO_CLUSTER = "none"
#: seconds to wait for a scheduler (``--cluster tcp://...``) and for its first worker
CONNECT_TIMEOUT_S = 10


class _Done:
    """An in-process result with the part of the ``distributed.Future`` interface the pool uses."""

    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


def _host(address: str) -> str:
    """``tcp://10.0.0.5:40123`` -> ``10.0.0.5`` (a worker's machine)."""
    rest = address.split("://", 1)[-1]
    return rest.rsplit(":", 1)[0] if ":" in rest else rest


class ClusterPool:
    """Where the work of ``crowd report`` and ``crowd build`` runs: dask.distributed, or this process.

    Parameters
    ----------
    cluster : str or None
        ``"local"`` (the default): an embedded ``LocalCluster`` on loopback (127.0.0.1, no dashboard), one
        single-threaded worker process per core of this machine, no memory limit (``crowd.memory`` guards the
        scenes), and dask's per-worker thread pinning (``OMP_NUM_THREADS=1`` ...) left out, so a timed run has
        the same numba, BLAS and llvmpipe threads as ``crowd run``. ``tcp://HOST:PORT``: a running scheduler
        (its workers need this package and the scenes' assets at the same paths; ``crowd build`` also needs
        the cache folder on a filesystem the workers share). ``"none"`` or None: this process, serially.

    Notes
    -----
    Scheduling. :meth:`timed` runs the timed work so that no two timed runs share a machine's cores: the
    workers are grouped by host (the host part of their addresses), each host gets one queue, and a host's
    next timed task is submitted (pinned to that host's workers) only when its previous one has finished;
    different hosts time in parallel. :meth:`timed` returns when all are done, and the report submits
    nothing else meanwhile, so no image-error work, reference run or build runs beside a timed run either
    (on any host of the cluster; other clients of a shared cluster are not controlled). Untimed work
    (:meth:`submit`) fills every worker. Results move between workers as futures; the client only writes
    them to the report folder.

    Raises
    ------
    crowd.errors.CrowdError
        dask.distributed is not installed, the address is malformed, or the scheduler cannot be reached.
    """

    def __init__(self, cluster: str | None = DEFAULT_CLUSTER):
        if cluster is not None and cluster != NO_CLUSTER and cluster != "local" and "://" not in cluster:
            raise CrowdError(f"--cluster {cluster!r}: expected 'local' (an embedded dask LocalCluster), 'none' "
                             "(this process) or the address tcp://HOST:PORT of a running dask scheduler")
        self.cluster_arg = None if cluster == NO_CLUSTER else cluster
        self._cluster, self._client = None, None
        self.description = "this process"

    @property
    def distributed(self) -> bool:
        """True when the work runs on a dask cluster."""
        return self._client is not None

    def __enter__(self):
        if self.cluster_arg is None:
            return self
        try:
            import dask
            from dask.distributed import Client, LocalCluster
        except ImportError:
            raise CrowdError(f"--cluster {self.cluster_arg}: dask.distributed is not installed "
                             "(pip install 'crowd-sandbox[report]' or pip install dask distributed); "
                             "--cluster none runs in this process") from None
        import logging
        import os
        import warnings

        try:
            if self.cluster_arg == "local":
                n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
                env = {k: v for k, v in (dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {}).items()
                       if not k.endswith("_NUM_THREADS")}
                with dask.config.set({"distributed.nanny.pre-spawn-environ": env}), warnings.catch_warnings():
                    warnings.filterwarnings("ignore", message=".*already in use")  # its HTTP port: any free one
                    self._cluster = LocalCluster(n_workers=max(1, n), threads_per_worker=1, processes=True,
                                                 host="127.0.0.1", dashboard_address=None, memory_limit=0,
                                                 silence_logs=logging.ERROR)
                self._client = Client(self._cluster)
                self.description = (f"embedded dask LocalCluster {self._cluster.scheduler_address} "
                                    f"({max(1, n)} single-threaded workers)")
            else:
                self._client = Client(self.cluster_arg, timeout=f"{CONNECT_TIMEOUT_S}s")
                self._client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
                self.description = f"dask scheduler {self.cluster_arg}"
        except (OSError, TimeoutError, ValueError) as e:
            self.__exit__()
            raise CrowdError(f"--cluster {self.cluster_arg}: cannot connect ({type(e).__name__}: {e}); expected "
                             "'local', 'none' or the address tcp://HOST:PORT of a running dask scheduler with "
                             "workers") from None
        return self

    def hosts(self) -> dict:
        """host -> sorted worker addresses on it ({"this process": []} without a cluster)."""
        if self._client is None:
            return {"this process": []}
        out = {}
        for addr, info in self._client.scheduler_info(n_workers=-1)["workers"].items():
            out.setdefault(info.get("host") or _host(addr), []).append(addr)
        return {h: sorted(v) for h, v in sorted(out.items())}

    def submit(self, fn, *args):
        """``fn(*args)`` as untimed work; args may be results of :meth:`submit`/:meth:`timed` (handles).
        Returns a handle (a ``distributed.Future``, or a finished in-process result)."""
        if self._client is None:
            return _Done(fn(*[a.value if isinstance(a, _Done) else a for a in args]))
        return self._client.submit(fn, *args, pure=False)

    def results(self, handles: list, done=None) -> list:
        """Values of ``handles`` in order; ``done()`` is called as each one finishes."""
        if self._client is None:
            for _ in handles:
                if done is not None:
                    done()
            return [h.value for h in handles]
        from distributed import as_completed

        for _ in as_completed(handles):
            if done is not None:
                done()
        return [h.result() for h in handles]

    def timed(self, fn, jobs: list, done=None) -> list:
        """``fn(*args)`` for each args of ``jobs``, never two on one host at a time (class Notes).

        Returns
        -------
        list of (handle, value) in the order of ``jobs``; ``done(index, value)`` is called as each one finishes
        (``index`` into ``jobs``).
        """
        out = [None] * len(jobs)
        if self._client is None:
            for i, a in enumerate(jobs):
                v = fn(*a)
                out[i] = (_Done(v), v)
                if done is not None:
                    done(i, v)
            return out
        from distributed import as_completed

        pending = list(enumerate(jobs))
        running, ac = {}, as_completed()

        def start(host, workers):
            if pending:
                i, a = pending.pop(0)
                f = self._client.submit(fn, *a, workers=workers, allow_other_workers=False, pure=False)
                running[f.key] = (i, host, workers)
                ac.add(f)

        for host, workers in self.hosts().items():
            start(host, workers)
        for f in ac:
            i, host, workers = running.pop(f.key)
            v = f.result()
            out[i] = (f, v)
            if done is not None:
                done(i, v)
            start(host, workers)
        return out

    def map(self, fn, args: list) -> list:
        """``[fn(*a) for a in args]`` as untimed work, results in order (array arguments are scattered to the
        workers, so they need no shared filesystem)."""
        if self._client is None:
            return [fn(*a) for a in args]
        futures, held = [], []
        for a in args:
            # hash=False: equal images (a NoLOD frame is its own reference) must not share, and then lose, one key;
            # the scattered futures are held until the results are back
            parts = self._client.scatter([x for x in a if x is not None], hash=False)
            held.append(parts)
            it = iter(parts)
            futures.append(self._client.submit(fn, *[next(it) if x is not None else None for x in a], pure=False))
        try:
            return self._client.gather(futures)
        finally:
            del held

    def __exit__(self, *exc):
        client, cluster = self._client, self._cluster
        self._client = self._cluster = None
        shutdown_dask(client, cluster)


#: the former name (image-error work only); same class
MetricsPool = ClusterPool


def shutdown_dask(client=None, cluster=None) -> None:
    """Close a dask client, then a cluster, quietly.

    Closing a ``LocalCluster`` waits a fixed 5 s (``distributed.nanny.Nanny.close``) for each worker process to
    exit before killing it; on a loaded machine that wait can time out after the work is complete, which is no
    error of the report: the timeout and the log lines it causes are swallowed (the processes are killed).
    """
    import asyncio
    import logging

    loggers = [logging.getLogger(n) for n in ("distributed", "tornado.application", "asyncio")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL)
    try:
        for obj in (client, cluster):
            if obj is None:
                continue
            try:
                obj.close()
            except (TimeoutError, asyncio.TimeoutError, asyncio.CancelledError, OSError, RuntimeError):
                pass
    finally:
        for lg, lv in zip(loggers, levels):
            lg.setLevel(lv)
