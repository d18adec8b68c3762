"""Running batches of trials on a Dask or Ray cluster.

The local executor (`store.execute`) runs batches in a process pool whose workers
write their trial files themselves. A cluster's workers need not share the results
folder, so here a batch's records travel back to this process, which writes each
trial's file atomically as its batch finishes (a stopped run loses only the batches
in flight). Where a batch runs never changes its numbers: a trial computes the same
alone, in any batch, on any worker.

- `dask`: `executor.address` is a `distributed` scheduler (``tcp://host:8786``); without
  one, a LocalCluster of `n_jobs` single-threaded worker processes is started.
- `ray`: `executor.address` is a Ray cluster (``ray://host:10001`` or ``auto``); without
  one, a local Ray instance with `n_jobs` CPUs is started.
"""

from __future__ import annotations

import socket
from collections.abc import Callable
from urllib.parse import urlsplit

from tavc_cli.errors import TavcError
from tavc_cli.experiments.build import Batch
from tavc_cli.experiments.contained import BatchResult, simulate_contained


def probe(backend: str, address: str | None, timeout_s: float = 5.0) -> None:
    """Stop with one line if `address` names a host and port nobody answers on; called before
    a run writes anything; ``auto`` and other addresses without a port are left to the backend."""
    if not address:
        return
    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        raise TavcError(f"executor.address: {address!r} is not a host:port address") from None
    if not host or port is None:
        return
    try:
        socket.create_connection((host, port), timeout=timeout_s).close()
    except OSError as exc:
        name = "Dask scheduler" if backend == "dask" else "Ray cluster"
        raise TavcError(f"executor.address: cannot reach the {name} at {address}: "
                        f"{exc.strerror or exc or 'no answer'}") from None


def simulate_batch(batch: Batch) -> BatchResult:
    """One batch's finished records and failed trials (what a cluster worker runs)."""
    return simulate_contained(batch.specs)


def _need(module: str, backend: str) -> None:
    try:
        __import__(module)
    except ImportError:
        raise TavcError(f"executor.backend={backend} needs {module}: pip install 'tavc[{backend}]'") from None


def run_on_cluster(backend: str, pending: list[Batch], save: Callable[[Batch, BatchResult], None],
                   n_jobs: int, address: str | None) -> None:
    """Run `pending` on the backend's cluster; `save` each batch's result as it finishes."""
    if backend == "dask":
        _need("distributed", backend)
        _run_dask(pending, save, n_jobs, address)
    elif backend == "ray":
        _need("ray", backend)
        _run_ray(pending, save, n_jobs, address)
    else:
        raise TavcError(f"executor.backend: no cluster executor {backend!r}")


def _run_dask(pending, save, n_jobs, address) -> None:
    # deferred: loads Dask (optional)
    from distributed import Client, LocalCluster, as_completed

    cluster = None
    try:
        if address:
            client = Client(address, timeout=20)
        else:
            cluster = LocalCluster(n_workers=n_jobs, threads_per_worker=1, processes=True, dashboard_address=None)
            client = Client(cluster)
    except OSError as exc:
        raise TavcError(f"executor.address: cannot reach the Dask scheduler {address}: {exc}") from None
    try:
        futures = {client.submit(simulate_batch, b, pure=False): b for b in pending}
        for future in as_completed(futures):
            batch = futures[future]
            save(batch, future.result())
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _run_ray(pending, save, n_jobs, address) -> None:
    # deferred: loads Ray (optional)
    import ray

    started = False
    if not ray.is_initialized():
        try:
            if address:
                ray.init(address=address, log_to_driver=False)
            else:
                ray.init(num_cpus=n_jobs, include_dashboard=False, log_to_driver=False)
        except ConnectionError as exc:
            raise TavcError(f"executor.address: cannot reach the Ray cluster {address}: {exc}") from None
        started = True
    try:
        remote = ray.remote(num_cpus=1)(simulate_batch)
        refs = {remote.remote(b): b for b in pending}
        left = list(refs)
        while left:
            ready, left = ray.wait(left, num_returns=1)
            batch = refs[ready[0]]
            save(batch, ray.get(ready[0]))
    finally:
        if started:
            ray.shutdown()
