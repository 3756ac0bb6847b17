"""The distributed engine of fleets and campaigns: Dask (`distributed`).

Its local cluster is the default: K worker processes of one thread each on this machine (every
task is a whole training or simulation, seconds long, against Dask's ~1 ms per task). A scheduler
address points the same command at a running cluster, whose workers must have this package
installed (`pip install -e .` in the same version) and see the data folders at the same paths.
"""
from __future__ import annotations

import logging
import os
import re
import threading
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager

from tqdm import tqdm

from contract.errors import ImuFusionError, one_line


#: How long to wait for a scheduler given by address [s]: for its answer, and again for its first worker.
CONNECT_TIMEOUT_S = 20
#: The addresses --scheduler accepts: Dask's network protocols with a host (name, IPv4 or [IPv6]) and a port.
ADDRESS_FORM = "tcp://HOST:PORT or tls://HOST:PORT, e.g. tcp://10.0.0.5:8786"
_ADDRESS = re.compile(r"^(tcp|tls)://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9][A-Za-z0-9.-]*):([0-9]{1,5})$")


class EngineError(ImuFusionError):
    """The Dask cluster could not be started or reached."""


def default_workers() -> int:
    """Workers of the local cluster when none is asked for: the cores this process may use."""
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def checked_address(address: str) -> str:
    """`address` when it has the form of ADDRESS_FORM with a port in 1..65535, else EngineError naming it."""
    match = _ADDRESS.match(address)
    if match is None or not 1 <= int(match.group(3)) <= 65535:
        raise EngineError(f"--scheduler {address!r}: not a Dask scheduler address ({ADDRESS_FORM})")
    return address


def connect(address: str):
    """A `distributed.Client` connected to the scheduler at `address` that has at least one worker,
    or EngineError naming the address, within 2 x CONNECT_TIMEOUT_S whatever the peer does: refuses
    the connection, accepts it and never answers, answers in another protocol (an HTTP server: its
    reply read as a Dask frame length asks for exabytes), or has no worker."""
    from distributed import Client
    outcome: dict = {}

    def attempt() -> None:
        try:
            outcome["client"] = Client(address, timeout=f"{CONNECT_TIMEOUT_S}s")
        except BaseException as e:  # noqa: BLE001 - whatever the peer made the client raise is reported
            outcome["error"] = e
            return
        try:
            outcome["client"].wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
        except BaseException as e:  # noqa: BLE001
            outcome["workers"] = e

    thread = threading.Thread(target=attempt, name="dask-connect", daemon=True)
    thread.start()
    thread.join(2 * CONNECT_TIMEOUT_S + 5)
    if thread.is_alive() or isinstance(outcome.get("error"), TimeoutError):
        raise EngineError(f"cannot reach the Dask scheduler at {address}: no Dask answer within "
                          f"{CONNECT_TIMEOUT_S} s (is a Dask scheduler listening there?)")
    if isinstance(outcome.get("error"), MemoryError):
        raise EngineError(f"cannot reach the Dask scheduler at {address}: the peer does not speak Dask's protocol "
                          f"(its reply, read as a Dask message: {one_line(str(outcome['error']))})")
    if "error" in outcome:
        e = outcome["error"]
        raise EngineError(f"cannot reach the Dask scheduler at {address}: {one_line(f'{type(e).__name__}: {e}')}")
    if "workers" in outcome:
        outcome["client"].close()
        raise EngineError(f"the Dask scheduler at {address} has no worker after {CONNECT_TIMEOUT_S} s: start "
                          "`dask worker ADDRESS` on the machines that should compute")
    return outcome["client"]


def _quiet_resource_tracker() -> None:
    """multiprocessing's resource tracker, started now with its shutdown warning silenced. A worker process
    that Ctrl-C stops in the middle of a task is killed with a semaphore still registered; the tracker
    removes it when the command ends (nothing leaks) but said so in a two-line UserWarning on stderr
    after `imufmu <verb>: interrupted`. The tracker reads the filter from its environment."""
    from multiprocessing import resource_tracker
    quiet = "ignore::UserWarning:multiprocessing.resource_tracker"
    if quiet not in os.environ.get("PYTHONWARNINGS", ""):
        os.environ["PYTHONWARNINGS"] = ",".join(filter(None, [os.environ.get("PYTHONWARNINGS"), quiet]))
    resource_tracker.ensure_running()


@contextmanager
def dask_client(workers: int | None = None, scheduler: str | None = None):
    """A `distributed.Client`: on a LocalCluster of `workers` single-threaded processes (default
    `default_workers()`), or connected to the scheduler at `scheduler` ("tcp://host:8786")."""
    from distributed import Client, LocalCluster
    if workers is not None and workers < 1:
        raise EngineError(f"--workers must be ≥ 1, got {workers}")
    if scheduler is not None:
        client = connect(checked_address(scheduler))
        try:
            yield client
        finally:
            client.close()
        return
    _quiet_resource_tracker()
    env = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}  # one core per worker process
    # the scheduler's HTTP server on a free port: with None it still tries 8787 and, on a machine where
    # another cluster holds it, warns in four lines on stderr
    with LocalCluster(n_workers=workers or default_workers(), threads_per_worker=1, processes=True,
                      dashboard_address=":0", silence_logs=logging.ERROR, env=env) as cluster, \
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
