"""Map a case function over many independent cases: in-process, on local processes, or on Ray.

Gain tuning with restarts, identification over many recordings, domain sweeps and the
doctor's blind benchmark are many independent simulations.  :func:`sweep` runs
``fn(case) -> dict`` for every case and returns one :class:`CaseResult` per case, in case
order, whatever the backend:

* ``"inline"``: in this process, one case after the other (also used for a single case);
* ``"process"`` (default): a pool of local worker processes, one per CPU.  Processes, not
  threads: the fluid layer holds the GIL.  Workers are started from a clean ``forkserver``
  (no inherited threads or locks) and stay alive for later sweeps in the same Python
  process, so each pays its imports and numba compilation once;
* ``"ray"``: tasks on a Ray cluster (``ray_address="auto"`` or ``"HOST:PORT"``), or on a
  Ray instance started here (``ray_address=None``).

With ``out`` each finished case is written at once (atomically) to ``out/cases/<index>.json``;
a rerun with the same ``out`` reuses every case whose file holds the same case dict and no
error (resume).  A case whose worker raises or dies (even SIGKILL) is retried ``retries``
times, then reported as failed with the worker's traceback summary: never a silent gap.
"""
from __future__ import annotations

import atexit
import contextlib
import copy
import json
import os
import pickle
import signal
import socket
import sys
import time
import traceback
import types
from collections import deque
from dataclasses import dataclass
from pathlib import Path

from .errors import ConfigError, PneumasimError, UnknownNameError
from .io import atomic_write_json
from .progress import plain_line, progress_mode

BACKENDS = ("inline", "process", "ray")


@dataclass
class CaseResult:
    """One case of a sweep.

    Attributes:
      index: position of the case in the list given to :func:`sweep`.
      case: the case dict (as JSON gives it back: tuples become lists).
      result: what ``fn`` returned (JSON round-tripped), or None if the case failed.
      error: None, or the worker's traceback summary after the last attempt.
      seconds: wall time of the case in its worker, summed over attempts [s].
      attempts: how many times it was run (0 if resumed from ``out``).
      resumed: True if read back from a previous run's ``out/cases/<index>.json``.
    """

    index: int
    case: dict
    result: dict | None
    error: str | None
    seconds: float
    attempts: int
    resumed: bool = False

    @property
    def ok(self) -> bool:
        return self.error is None


def sweep(fn, cases, *, out=None, backend="process", workers=None, ray_address=None,
          retries=1, progress=True) -> list[CaseResult]:
    """Run ``fn(case)`` for every case; results in case order.

    Args:
      fn: a top-level (picklable) function ``fn(case: dict) -> dict`` whose result is
        JSON-serialisable (numpy scalars and arrays are converted).  Seed any randomness
        from the case, so that every backend gives the same results.
      cases: a sequence of JSON-serialisable dicts.
      out: folder for ``cases/<index>.json`` (one per finished case) and ``sweep.json``
        (summary); with it, a rerun skips the cases already finished.
      backend: ``"inline"``, ``"process"`` or ``"ray"``; giving ``ray_address`` selects Ray.
      workers: parallel cases (default: the CPUs of this machine, or of the Ray cluster).
      ray_address: ``"auto"`` (the cluster ``ray start`` made), ``"HOST:PORT"``,
        ``"ray://HOST:10001"``, or None to start Ray locally.  A Ray already initialised
        in this process (``ray.init``) is used as it is.
      retries: extra attempts for a case that raised or whose worker died.
      progress: show a progress bar (cases done, failed, time left) on stderr.
    """
    if backend not in BACKENDS:
        raise UnknownNameError("sweep backend", str(backend), BACKENDS)
    if ray_address is not None and backend == "process":
        backend = "ray"
    if ray_address is not None and backend != "ray":
        raise ConfigError(f"sweep: ray_address={ray_address!r} needs backend='ray', not {backend!r}")
    if not isinstance(retries, int) or retries < 0:
        raise ConfigError(f"sweep: retries = {retries!r}; expected a whole number >= 0")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise ConfigError(f"sweep: workers = {workers!r}; expected a whole number >= 1")
    if not callable(fn):
        raise ConfigError(f"sweep: fn = {fn!r} is not a function")
    cases = [_plain_case(c, i) for i, c in enumerate(cases)]
    out = Path(out) if out is not None else None
    results: list[CaseResult | None] = _resume(out, cases) if out else [None] * len(cases)
    todo = [i for i, r in enumerate(results) if r is None]
    if backend == "process" and len(todo) == 1:
        backend = "inline"  # nothing to share: no pool start
    if backend != "inline" and todo:
        _check_picklable(fn, backend)
    t0 = time.perf_counter()
    n_workers = None
    with _Bar(len(cases), len(cases) - len(todo), progress, getattr(fn, "__name__", "sweep")) as bar:

        def finish(i, result, error, seconds, attempts):
            results[i] = CaseResult(i, cases[i], result, error, seconds, attempts)
            if out:
                atomic_write_json(out / "cases" / f"{i}.json",
                                  {"index": i, "case": cases[i], "result": result, "error": error,
                                   "seconds": seconds, "attempts": attempts, "backend": backend,
                                   "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())})
            bar.advance(error is not None)

        tracker = _Tracker(todo, retries, finish, bar)
        if todo:
            if backend == "inline":
                n_workers = 1
                _run_inline(fn, cases, tracker)
            elif backend == "process":
                n_workers = min(workers or _cpu_count(), len(todo))
                _run_process(fn, cases, tracker, n_workers)
            else:
                n_workers = _run_ray(fn, cases, tracker, workers, ray_address)
    failed = [r.index for r in results if not r.ok]
    if out:
        atomic_write_json(out / "sweep.json", {
            "cases": len(cases), "done": len(cases) - len(failed), "failed": len(failed),
            "resumed": sum(r.resumed for r in results), "failed_cases": failed, "backend": backend,
            "workers": n_workers, "wall_seconds": round(time.perf_counter() - t0, 3)})
    if failed and progress:
        for i in failed[:5]:
            print(f"sweep: case {i} failed after {results[i].attempts} attempt(s):\n  "
                  + results[i].error.replace("\n", "\n  "), file=sys.stderr)
    return results


def raise_on_failure(results: list[CaseResult], what: str = "sweep"):
    """Raise a :class:`PneumasimError` naming the failed cases and the first error."""
    bad = [r for r in results if not r.ok]
    if bad:
        raise PneumasimError(f"{what}: {len(bad)} of {len(results)} cases failed (indices "
                             f"{[r.index for r in bad][:20]}); case {bad[0].index}: {bad[0].error.splitlines()[0]}")


def options_from_env() -> dict:
    """Backend options from the environment, for scenarios (which take no sweep flags):
    ``PNEUMASIM_RAY=auto|ADDRESS|local`` selects Ray (``local``: start it here),
    ``PNEUMASIM_WORKERS=N`` the number of workers, ``PNEUMASIM_BACKEND=inline|process|ray``."""
    opts = {}
    backend = os.environ.get("PNEUMASIM_BACKEND")
    if backend:
        opts["backend"] = backend
    ray_address = os.environ.get("PNEUMASIM_RAY")
    if ray_address:
        opts["backend"] = "ray"
        if ray_address != "local":
            opts["ray_address"] = ray_address
    n = os.environ.get("PNEUMASIM_WORKERS")
    if n:
        try:
            opts["workers"] = int(n)
        except ValueError:
            raise ConfigError(f"PNEUMASIM_WORKERS = {n!r}; expected a whole number >= 1") from None
    return opts


def load_function(target: str):
    """``"package.module:function"`` -> the function (for ``pneumasim sweep``)."""
    import importlib

    module, sep, name = target.partition(":")
    if os.getcwd() not in sys.path:  # as `python -m` does: modules in the current folder import
        sys.path.insert(0, os.getcwd())
    if not sep or not module or not name:
        raise ConfigError(f"sweep: {target!r}; expected MODULE:FUNCTION, e.g. scenarios.arm2_domain_sweep:track")
    try:
        mod = importlib.import_module(module)
    except ImportError as e:
        raise ConfigError(f"sweep: cannot import module {module!r}: {e}") from None
    fn = getattr(mod, name, None)
    if not callable(fn):
        raise ConfigError(f"sweep: module {module!r} has no function {name!r}")
    return fn


def read_cases(path: str | Path) -> list[dict]:
    """Cases from a JSON file (a list of objects) or a JSON-lines file (one object a line)."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise ConfigError(f"{path}: cannot read the cases file ({e.strerror})") from None
    try:
        cases = json.loads(text)
    except ValueError:
        try:
            cases = [json.loads(line) for line in text.splitlines() if line.strip()]
        except ValueError as e:
            raise ConfigError(f"{path}: neither a JSON list nor JSON lines: {e}") from None
    if not isinstance(cases, list) or not all(isinstance(c, dict) for c in cases):
        raise ConfigError(f"{path}: expected a JSON list of objects (one per case)")
    return cases


# ---------------------------------------------------------------- cases, results, resume

def _json_default(x):
    if hasattr(x, "tolist"):  # numpy scalars and arrays
        return x.tolist()
    raise TypeError(f"{type(x).__name__} is not JSON-serialisable")


def _plain_case(case, i) -> dict:
    if not isinstance(case, dict):
        raise ConfigError(f"sweep: case {i} is a {type(case).__name__}; expected a dict")
    try:
        return json.loads(json.dumps(case, default=_json_default))
    except (TypeError, ValueError) as e:
        raise ConfigError(f"sweep: case {i} is not JSON-serialisable: {e}") from None


def _resume(out: Path, cases: list[dict]) -> list[CaseResult | None]:
    """Finished cases of an earlier run into ``out`` (same case dict, no error)."""
    results = []
    for i, case in enumerate(cases):
        path = out / "cases" / f"{i}.json"
        try:
            rec = json.loads(path.read_text())
        except (OSError, ValueError):
            results.append(None)
            continue
        same = isinstance(rec, dict) and rec.get("case") == case and rec.get("error") is None and "result" in rec
        results.append(CaseResult(i, case, rec["result"], None, float(rec.get("seconds", 0.0)), 0, True)
                       if same else None)
    return results


def _error_summary(e: BaseException) -> str:
    """The exception and the innermost frames: what a user needs to find the fault."""
    tb = traceback.TracebackException.from_exception(e)
    head = "".join(tb.format_exception_only()).strip()
    stack = [f for f in tb.stack if f.filename != __file__]  # not the sweep's own frames
    frames = [f"  at {Path(f.filename).name}:{f.lineno} in {f.name}" for f in stack[-3:]][::-1]
    return "\n".join([head, *frames])


def _one_thread():
    """BLAS and OpenMP limited to one thread while a case runs, on every backend: a
    multi-threaded BLAS sums in another order (results differ in the last digits) and Ray
    workers are single-threaded by default (OMP_NUM_THREADS=1); parallelism comes from the
    workers, and one thread each avoids oversubscribing the cores."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a dependency; without it, bits may differ
        return contextlib.nullcontext()
    return threadpool_limits(limits=1)


def _call(fn, case: dict):
    """Run one case; never raises (an Exception becomes the error string)."""
    t0 = time.perf_counter()
    try:
        with _one_thread():
            result = fn(case)
        if not isinstance(result, dict):
            raise TypeError(f"case function {getattr(fn, '__name__', fn)!r} returned a "
                            f"{type(result).__name__}; expected a dict")
        result, error = json.loads(json.dumps(result, default=_json_default)), None
    except Exception as e:  # noqa: BLE001 - reported per case
        result, error = None, _error_summary(e)
    return result, error, time.perf_counter() - t0


class _Tracker:
    """The queue of cases to run, their attempts, and the retry rule."""

    def __init__(self, todo, retries, finish, bar):
        self.queue = deque(todo)
        self.attempts = dict.fromkeys(todo, 0)
        self.seconds = dict.fromkeys(todo, 0.0)
        self.retries, self.finish, self.bar = retries, finish, bar

    def next(self) -> int:
        i = self.queue.popleft()
        self.attempts[i] += 1
        return i

    def done(self, i, result, error, seconds):
        self.seconds[i] += seconds
        if error is not None and self.attempts[i] <= self.retries:
            self.queue.appendleft(i)
            self.bar.retried()
            return
        self.finish(i, result, error, self.seconds[i], self.attempts[i])


def _run_inline(fn, cases, tracker):
    while tracker.queue:
        i = tracker.next()
        tracker.done(i, *_call(fn, copy.deepcopy(cases[i])))


def _cpu_count() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _check_picklable(fn, backend):
    name = getattr(fn, "__qualname__", repr(fn))
    hint = ("define it with `def` at the top level of a module (not a lambda, a nested function or a "
            "bound method of an unpicklable object), or use backend='inline'")
    try:
        pickle.loads(pickle.dumps(fn))
    except Exception as e:  # noqa: BLE001
        raise ConfigError(f"sweep: the case function {name!r} cannot be sent to {backend} workers "
                          f"({type(e).__name__}: {e}); {hint}") from None
    main = sys.modules.get("__main__")
    if backend == "process" and getattr(fn, "__module__", None) == "__main__" and not getattr(main, "__file__", None):
        raise ConfigError(f"sweep: the case function {name!r} is defined in an interactive session; "
                          f"worker processes cannot import it: {hint}")


# ---------------------------------------------------------------- local process pool

def _worker_loop(conn):
    """A worker process: receive (index, pickled fn, case), send (index, result, error, s)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C and stops us
    fns = {}
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):  # the parent is gone
            return
        if msg is None:
            return
        index, fn_bytes, case = msg
        try:
            if fn_bytes not in fns:
                fns = {fn_bytes: pickle.loads(fn_bytes)}
            reply = (index, *_call(fns[fn_bytes], case))
        except Exception as e:  # noqa: BLE001 - e.g. the function's module does not import here
            reply = (index, None, "could not load the case function in the worker: " + _error_summary(e), 0.0)
        try:
            conn.send(reply)
        except (BrokenPipeError, OSError):
            return


class _Worker:
    def __init__(self, ctx):
        self.conn, child = ctx.Pipe()
        # not daemonic, so that a case function may itself start processes
        self.proc = ctx.Process(target=_worker_loop, args=(child,), name="pneumasim-sweep-worker")
        self.proc.start()
        child.close()
        self.index, self.started = None, 0.0

    def stop(self, timeout=2.0):
        try:
            self.conn.send(None)
        except (BrokenPipeError, OSError):
            pass
        self.proc.join(timeout)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join()
        self.conn.close()


class _Pool:
    """Worker processes kept for the life of this Python process (warm imports and JIT)."""

    def __init__(self):
        self.workers: list[_Worker] = []
        self.ctx = None
        self.need_main = False

    def take(self, n: int, preload: list[str], need_main: bool) -> list[_Worker]:
        import multiprocessing as mp
        import multiprocessing.util  # registers its exit hook before ours (see below)

        if self.ctx is None:
            method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
            self.ctx = mp.get_context(method)
            # after multiprocessing's own exit hook (atexit runs last-in first-out), which
            # would otherwise wait forever for our idle workers
            atexit.register(self.shutdown)
            if method == "forkserver":
                self.ctx.set_forkserver_preload(preload)
        self.workers = [w for w in self.workers if w.proc.is_alive()]
        self.need_main = need_main
        while len(self.workers) < n:
            self.workers.append(self._start())
        return self.workers[:n]

    def _start(self) -> _Worker:
        """A new worker.  Unless fn lives in the main script, the worker is started without
        re-running that script (what spawn/forkserver do by default): a script that calls
        sweep() without an ``if __name__ == "__main__":`` guard then still works."""
        if self.need_main:
            return _Worker(self.ctx)
        main = sys.modules["__main__"]
        sys.modules["__main__"] = types.ModuleType("__main__")
        try:
            return _Worker(self.ctx)
        finally:
            sys.modules["__main__"] = main

    def replace(self, w: _Worker) -> _Worker:
        w.proc.join(0.1)
        if w.proc.is_alive():
            w.proc.kill()
            w.proc.join()
        w.conn.close()
        new = self._start()
        self.workers[self.workers.index(w)] = new
        return new

    def shutdown(self):
        for w in self.workers:
            w.stop()
        self.workers = []

    def kill(self):
        for w in self.workers:
            w.proc.kill()
        for w in self.workers:
            w.proc.join()
            w.conn.close()
        self.workers = []


_POOL = _Pool()


def shutdown_pool():
    """Stop the local worker processes kept between sweeps (they stop at exit anyway)."""
    _POOL.shutdown()


def _exit_text(code) -> str:
    if code is not None and code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


def _run_process(fn, cases, tracker, n_workers):
    from multiprocessing.connection import wait

    fn_bytes = pickle.dumps(fn)
    preload = [m for m in ("pneumatics.sweep", getattr(fn, "__module__", None)) if m and m != "__main__"]
    idle = list(_POOL.take(n_workers, preload, need_main=getattr(fn, "__module__", None) == "__main__"))
    busy: dict = {}  # conn or sentinel -> worker
    try:
        while tracker.queue or busy:
            while idle and tracker.queue:
                w = idle.pop()
                i = tracker.next()
                w.index, w.started = i, time.perf_counter()
                try:
                    w.conn.send((i, fn_bytes, cases[i]))
                except (BrokenPipeError, OSError):
                    pass  # died while idle: the sentinel below reports it
                busy[w.conn] = busy[w.proc.sentinel] = w
            ready = wait(list(busy), timeout=0.5)
            tracker.bar.refresh()
            for key in ready:
                w = busy.get(key)
                if w is None:  # both its conn and its sentinel were ready; handled
                    continue
                msg = None
                try:
                    if w.conn.poll():
                        msg = w.conn.recv()
                except (EOFError, OSError):
                    msg = None
                del busy[w.conn], busy[w.proc.sentinel]
                if msg is not None:
                    tracker.done(*msg)
                    idle.append(w)
                    continue
                w.proc.join(1.0)
                err = (f"worker process {w.proc.pid} died ({_exit_text(w.proc.exitcode)}) "
                       f"while running case {w.index}")
                i, secs = w.index, time.perf_counter() - w.started
                idle.append(_POOL.replace(w))
                tracker.done(i, None, err, secs)
    except BaseException:
        _POOL.kill()  # busy workers would answer into the next sweep
        raise


# ---------------------------------------------------------------- Ray

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
    return _call(_FN_CACHE[fn_bytes], case)


_RAY_REMOTE = None


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
            ray.init(num_cpus=num_cpus or _cpu_count(), include_dashboard=False, logging_level=logging.WARNING)
        else:
            ray.init(address=address, logging_level=logging.WARNING)
    except (ConnectionError, RuntimeError, ValueError) as e:
        raise PneumasimError(f"sweep: Ray not reachable at {address!r}: {str(e).splitlines()[0]}; start a "
                             "cluster with `ray start --head` (or give no address to start Ray here)") from None
    return ray


def _run_ray(fn, cases, tracker, workers, address) -> int:
    global _RAY_REMOTE
    ray = connect_ray(address, workers)
    from ray import cloudpickle

    if _RAY_REMOTE is None:
        # retries are ours (one rule for every backend), so Ray's own are off
        _RAY_REMOTE = ray.remote(num_cpus=1, max_retries=0)(_ray_call)
    payload = ray.put((cloudpickle.dumps(fn), [p for p in sys.path if p and os.path.isdir(p)]))
    window = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
    inflight: dict = {}  # ObjectRef -> (index, start)
    try:
        while tracker.queue or inflight:
            while tracker.queue and len(inflight) < window:
                i = tracker.next()
                inflight[_RAY_REMOTE.remote(payload, cases[i])] = (i, time.perf_counter())
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


# ---------------------------------------------------------------- progress

class _Bar:
    """Cases done of total, failed, retries, elapsed and time left: a rich progress bar on a
    terminal, else one plain timestamped line on stderr per finished case (pneumatics.progress)."""

    def __init__(self, total, done, enabled, label):
        self.total, self.enabled, self.failed, self.retries = total, enabled and total > 0, 0, 0
        self.label, self.done0, self.done = label, done, done
        self.progress = self.task = None
        self.plain = self.enabled and progress_mode() != "rich"
        self.silent = progress_mode() == "none"
        self.t0 = time.perf_counter()

    def _line(self, msg):
        if not self.silent:
            print(plain_line(f"sweep {self.label}", msg, self.t0), file=sys.stderr, flush=True)

    def __enter__(self):
        if self.plain:
            self._line(f"{self.total} cases" + (f", {self.done0} resumed" if self.done0 else ""))
        elif self.enabled:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self.progress = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                     TextColumn("failed {task.fields[failed]}  retries {task.fields[retries]}"),
                                     TimeElapsedColumn(), TextColumn("left"), TimeRemainingColumn(),
                                     console=Console(stderr=True))
            self.progress.start()
            desc = f"sweep {self.label}" + (f" ({self.done0} resumed)" if self.done0 else "")
            self.task = self.progress.add_task(desc, total=self.total, completed=self.done0, failed=0, retries=0)
        return self

    def advance(self, failed: bool):
        self.failed += failed
        self.done += 1
        if self.plain:
            ran, left = self.done - self.done0, self.total - self.done
            eta = (time.perf_counter() - self.t0) / ran * left
            self._line(f"{self.done}/{self.total} done, {self.failed} failed, {self.retries} retries"
                       + (f", ~{eta:.0f} s left" if left else ""))
        if self.progress:
            self.progress.update(self.task, advance=1, failed=self.failed)

    def retried(self):
        self.retries += 1
        if self.progress:
            self.progress.update(self.task, retries=self.retries)

    def refresh(self):
        if self.progress:
            self.progress.refresh()

    def __exit__(self, *exc):
        if self.progress:
            self.progress.stop()
        return False

