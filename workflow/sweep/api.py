"""The sweep itself: check the arguments, resume, run every case on the chosen backend,
write each finished case and the summary, return the results in case order."""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from pneumatics.errors import ConfigError, PneumasimError, UnknownNameError
from pneumatics.io import atomic_write_json

from .cases import CaseResult, Tracker, check_picklable, cpu_count, plain_case, resume_cases, run_inline
from .pool import run_process
from .progress import ProgressBar
from .ray_backend import run_ray

BACKENDS = ("inline", "process", "ray")


def sweep(fn, cases, *, out=None, backend="process", workers=None, ray_address=None,
          retries=1, progress=True, fresh_workers=False) -> list[CaseResult]:
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
      fresh_workers: run every case in a worker process of its own, started for it (as a
        user runs one command per process): what a case measures of its process -- its
        peak memory above all -- is then its own, not what earlier cases left resident.
        Costs a worker start (imports, numba's cache) per case; not with ``"inline"``.
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
    if fresh_workers and backend == "inline":
        raise ConfigError("sweep: fresh_workers=True needs worker processes; backend 'inline' runs the "
                          "cases in this process (use 'process' or 'ray')")
    cases = [plain_case(c, i) for i, c in enumerate(cases)]
    out = Path(out) if out is not None else None
    results: list[CaseResult | None] = resume_cases(out, cases) if out else [None] * len(cases)
    todo = [i for i, r in enumerate(results) if r is None]
    if backend == "process" and len(todo) == 1 and not fresh_workers:
        backend = "inline"  # nothing to share: no pool start
    if backend != "inline" and todo:
        check_picklable(fn, backend)
    t0 = time.perf_counter()
    n_workers = None
    with ProgressBar(len(cases), len(cases) - len(todo), progress, getattr(fn, "__name__", "sweep")) as bar:

        def finish(i, result, error, seconds, attempts):
            results[i] = CaseResult(i, cases[i], result, error, seconds, attempts)
            if out:
                atomic_write_json(out / "cases" / f"{i}.json",
                                  {"index": i, "case": cases[i], "result": result, "error": error,
                                   "seconds": seconds, "attempts": attempts, "backend": backend,
                                   "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())})
            bar.advance(error is not None)

        tracker = Tracker(todo, retries, finish, bar)
        if todo:
            if backend == "inline":
                n_workers = 1
                run_inline(fn, cases, tracker)
            elif backend == "process":
                n_workers = min(workers or cpu_count(), len(todo))
                run_process(fn, cases, tracker, n_workers, fresh_workers)
            else:
                n_workers = run_ray(fn, cases, tracker, workers, ray_address, fresh_workers)
    failed = [r.index for r in results if not r.ok]
    if out:
        atomic_write_json(out / "sweep.json", {
            "cases": len(cases), "done": len(cases) - len(failed), "failed": len(failed),
            "resumed": sum(r.resumed for r in results), "failed_cases": failed, "backend": backend,
            "workers": n_workers, "fresh_workers": bool(fresh_workers), "wall_seconds": round(time.perf_counter() - t0, 3)})
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
    ``PNEUMASIM_WORKERS=N`` the number of workers, ``PNEUMASIM_BACKEND=inline|process|ray``,
    ``PNEUMASIM_FRESH_WORKERS=1`` a worker process started for every case (``sweep``'s
    ``fresh_workers``)."""
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
    fresh = os.environ.get("PNEUMASIM_FRESH_WORKERS")
    if fresh:
        if fresh not in ("0", "1"):
            raise ConfigError(f"PNEUMASIM_FRESH_WORKERS = {fresh!r}; expected 1 (a worker per case) or 0")
        opts["fresh_workers"] = fresh == "1"
    return opts
