"""Cases as Ray tasks, on a cluster (``ray start``) or on a Ray started here."""
from __future__ import annotations

import os
import socket
import sys
import time

from pneumatics.errors import ConfigError, PneumasimError

from .cases import call_case, cpu_count

_FN_CACHE: dict = {}


def _ray_call(payload, case):
    """Runs in a Ray worker: make the driver's import paths visible, unpickle fn, run the case."""
    fn_bytes, paths = payload
    for p in paths:
        if p not in sys.path and os.path.isdir(p):
            sys.path.append(p)
    if fn_bytes not in _FN_CACHE:
        from ray import cloudpickle

        _FN_CACHE.clear()
        _FN_CACHE[fn_bytes] = cloudpickle.loads(fn_bytes)
    return call_case(_FN_CACHE[fn_bytes], case)


#: the remote function, one per value of max_calls (0: workers kept; 1: a worker per case);
#: Ray's .options() cannot override max_calls
_RAY_REMOTES: dict = {}


def _import_ray():
    try:
        import ray
    except ImportError:
        raise PneumasimError("sweep: backend 'ray' needs Ray: pip install 'ray>=2.40'") from None
    return ray


def _check_reachable(address: str, timeout_s: float = 5.0):
    """Fail fast (ray.init retries for a minute) if nothing listens at HOST:PORT."""
    hostport = address.split("://", 1)[-1]
    host, _, port = hostport.rpartition(":")
    if not host or not port.isdigit():
        raise ConfigError(f"sweep: ray_address {address!r}; expected 'auto', 'HOST:PORT' or 'ray://HOST:PORT'")
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as e:
        raise PneumasimError(f"sweep: Ray not reachable at {address} ({e}); start a cluster with "
                             "`ray start --head` on the head machine and pass the address it prints") from None


def connect_ray(address=None, num_cpus=None):
    """Connect to (``address``) or start (None) Ray unless this process already did; returns ray."""
    import logging

    ray = _import_ray()
    if address not in (None, "auto", "local"):
        _check_reachable(address)
    if ray.is_initialized():
        return ray
    try:
        if address is None:
            ray.init(num_cpus=num_cpus or cpu_count(), include_dashboard=False, logging_level=logging.WARNING)
        else:
            ray.init(address=address, logging_level=logging.WARNING)
    except (ConnectionError, RuntimeError, ValueError) as e:
        raise PneumasimError(f"sweep: Ray not reachable at {address!r}: {str(e).splitlines()[0]}; start a "
                             "cluster with `ray start --head` (or give no address to start Ray here)") from None
    return ray


def run_ray(fn, cases, tracker, workers, address, fresh_workers=False) -> int:
    ray = connect_ray(address, workers)
    from ray import cloudpickle

    # retries are ours (one rule for every backend), so Ray's own are off; Ray ends a worker
    # process after max_calls tasks of the function (0: never), so 1 gives every case its own
    max_calls = 1 if fresh_workers else 0
    if max_calls not in _RAY_REMOTES:
        _RAY_REMOTES[max_calls] = ray.remote(num_cpus=1, max_retries=0, max_calls=max_calls)(_ray_call)
    remote = _RAY_REMOTES[max_calls]
    payload = ray.put((cloudpickle.dumps(fn), [p for p in sys.path if p and os.path.isdir(p)]))
    window = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
    inflight: dict = {}  # ObjectRef -> (index, start)
    try:
        while tracker.queue or inflight:
            while tracker.queue and len(inflight) < window:
                i = tracker.next()
                inflight[remote.remote(payload, cases[i])] = (i, time.perf_counter())
            ready, _ = ray.wait(list(inflight), num_returns=1, timeout=0.5)
            tracker.bar.refresh()
            for ref in ready:
                i, t0 = inflight.pop(ref)
                try:
                    tracker.done(i, *ray.get(ref))
                except ray.exceptions.RayError as e:
                    first = str(e).strip().splitlines()[0] if str(e).strip() else ""
                    tracker.done(i, None, f"Ray task failed ({type(e).__name__}): {first}", time.perf_counter() - t0)
    except BaseException:
        for ref in inflight:
            ray.cancel(ref, force=True)
        raise
    return window
