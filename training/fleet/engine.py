"""The distributed engine of fleets and campaigns: Dask (`distributed`).

Its local cluster is the default: K worker processes of one thread each on this machine (every
task is a whole training or simulation, seconds long, against Dask's ~1 ms per task). A scheduler
address points the same command at a running cluster, whose workers must have this package
installed (`pip install -e .` in the same version) and see the data folders at the same paths.
"""
from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager

from tqdm import tqdm

from contract.errors import ImuFusionError


#: How long to wait for a scheduler given by address [s].
CONNECT_TIMEOUT_S = 20


class EngineError(ImuFusionError):
    """The Dask cluster could not be started or reached."""


def default_workers() -> int:
    """Workers of the local cluster when none is asked for: the cores this process may use."""
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


@contextmanager
def dask_client(workers: int | None = None, scheduler: str | None = None):
    """A `distributed.Client`: on a LocalCluster of `workers` single-threaded processes (default
    `default_workers()`), or connected to the scheduler at `scheduler` ("tcp://host:8786")."""
    from distributed import Client, LocalCluster
    if workers is not None and workers < 1:
        raise EngineError(f"--workers must be ≥ 1, got {workers}")
    if scheduler:
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError) as e:
            raise EngineError(f"cannot reach the Dask scheduler at {scheduler}: {e}") from None
        try:
            yield client
        finally:
            client.close()
        return
    env = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}  # one core per worker process
    with LocalCluster(n_workers=workers or default_workers(), threads_per_worker=1, processes=True,
                      dashboard_address=None, silence_logs=logging.ERROR, env=env) as cluster, \
            Client(cluster) as client:
        yield client


def run_tasks(client, function: Callable, items: Iterable, description: str, progress: bool = True,
              unit: str = "unit", **kwargs) -> Iterator[tuple[object, object]]:
    """Run function(item, **kwargs) for every item on the cluster, one task each; yields
    (item, result) as tasks finish, with a progress bar over the items. A task that raises is
    the caller's concern: `function` should return its failure instead."""
    items = list(items)
    futures = client.map(function, items, pure=False, **kwargs)
    index = {f.key: item for f, item in zip(futures, items)}
    from distributed import as_completed
    with tqdm(total=len(items), desc=description, unit=unit, disable=not progress) as bar:
        for future in as_completed(futures):
            yield index[future.key], future.result()
            bar.update()
