"""The batch on a ``dask.distributed`` cluster: one task per input file.

``--workers N`` starts a :class:`distributed.LocalCluster` of N worker processes with one thread
each (``bpy`` is not thread-safe; each worker process holds its own Blender session, reset by
every file it converts, and uses it from one thread only, whatever threads the worker has);
``--scheduler tcp://HOST:PORT`` uses a running scheduler whose workers have ``bidegree`` and
``bpy`` installed and see the same paths (inputs and output folder) as the client, which writes
the manifest.

Failures are handled by distributed itself, not here:

* a worker that dies while it converts a file (killed, out of memory) makes the scheduler run
  the task again on another worker, up to ``allowed-failures`` times (the ``--retries`` given to
  a local cluster; a running scheduler keeps its own ``distributed.scheduler.allowed-failures``),
  after which the file fails with distributed's ``KilledWorker``;
* a task that raises (only ``OSError`` and ``MemoryError`` do, see
  :func:`~bidegree_blender.batch.convert.convert_file`) is run again ``retries`` times.

The attempts a file took are the scheduler's own counts for its task, read when the task finishes
and written to the manifest: the workers that died while they held it (running it, or with it
waiting in their queue, which distributed counts towards ``allowed-failures`` too), plus the
retries used, plus the last attempt unless its worker died too (``KilledWorker``). A running
scheduler should set ``distributed.scheduler.worker-saturation: 1.0`` as the local cluster does,
so that a worker holds only the file it converts.
"""

from __future__ import annotations

import logging
import uuid
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from .convert import FileRecord, Job, convert_file, failed_record


class FarmError(Exception):
    """The cluster cannot be used (``distributed`` missing, scheduler unreachable)."""


def require_distributed() -> None:
    """Raise :class:`FarmError` when ``dask.distributed`` is not installed."""
    try:
        import distributed  # noqa: F401
    except ImportError as exc:
        raise FarmError(
            "--workers and --scheduler need dask.distributed: pip install 'bidegree[farm]'"
        ) from exc


#: The one thread of a worker process that imports and uses ``bpy`` (it is not thread-safe, and
#: Blender takes the thread that imported it for its main thread): one file at a time on it, even
#: in a worker started with several threads.
_BPY_THREAD = ThreadPoolExecutor(max_workers=1, thread_name_prefix="bidegree-bpy")


def convert_task(path: str, job: Job) -> FileRecord:
    """A worker's task: :func:`convert_file` on the ``bpy`` thread, tagged with the worker."""
    from distributed import get_worker

    record = _BPY_THREAD.submit(convert_file, path, job).result()
    record.worker = get_worker().address
    return record


def _interruptions_probe() -> Callable[..., tuple[int, int] | None]:
    """A function for ``Client.run_on_scheduler``: how often the task ``key`` was started again.

    Returns the workers that died holding it (the scheduler's ``suspicious`` count) and the
    retries it used (``retries`` counts down), or ``None`` for a task the scheduler forgot.
    Defined inside a function so that cloudpickle sends it by value (a scheduler does not need
    ``bidegree`` installed).
    """

    def interruptions(key: str, retries: int, dask_scheduler: Any = None) -> Any:
        ts = dask_scheduler.tasks.get(key)
        if ts is None:
            return None
        return int(ts.suspicious), max(0, retries - int(ts.retries))

    return interruptions


def _client(scheduler: str | None, workers: int | None, retries: int) -> tuple[Any, Any]:
    """A connected client, and the local cluster it owns (or ``None``)."""
    import dask
    from distributed import Client, LocalCluster

    if workers is not None:
        config = {
            # Saturation 1: a worker holds only the file it converts (once there are more files
            # than twice the workers, distributed's queuing applies), so a worker that dies costs
            # an attempt of that file alone and a free worker takes the next file, however long.
            "distributed.scheduler.worker-saturation": 1.0,
            # glibc's own trim threshold, as Blender runs: distributed's 64 KiB returns memory to
            # the system after every large free, which cost 20-40% more CPU time per file here.
            "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
        }
        with dask.config.set(config):
            cluster = LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                scheduler_kwargs={"allowed_failures": retries},
                silence_logs=logging.WARNING,
            )
        return Client(cluster), cluster
    try:
        return Client(scheduler, timeout="20s"), None
    except (OSError, ValueError) as exc:
        raise FarmError(f"cannot connect to the scheduler {scheduler}: {exc}") from exc


def run_distributed(
    inputs: Sequence[str],
    job: Job,
    on_record: Callable[[FileRecord], None],
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    retries: int = 2,
) -> None:
    """Convert ``inputs`` on a cluster, calling ``on_record`` as each file finishes.

    Exactly one of ``scheduler`` (an address) and ``workers`` (a local cluster's size) is given.
    """
    from distributed import KilledWorker, as_completed

    client, cluster = _client(scheduler, workers, retries)
    interruptions = _interruptions_probe()
    run_id = uuid.uuid4().hex[:8]
    futures: dict[Any, str] = {}
    try:
        for i, path in enumerate(inputs):
            key = f"bidegree-convert-{run_id}-{i}"  # one task group: "bidegree-convert"
            future = client.submit(convert_task, path, job, key=key, pure=False, retries=retries)
            futures[future] = path
        for future in as_completed(futures):
            path = futures[future]
            last_ran = 1  # the last attempt ran to its end (its worker did not die)
            try:
                record = future.result()
            except KilledWorker as exc:
                record, last_ran = failed_record(path, job, exc), 0
            except Exception as exc:  # OSError / MemoryError after its retries
                record = failed_record(path, job, exc)
            counts = client.run_on_scheduler(interruptions, key=future.key, retries=retries)
            if counts is not None:
                record.attempts = sum(counts) + last_ran
            future.release()
            on_record(record)
    except BaseException:
        client.cancel(list(futures))
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
