"""Cases and their results: the case function's loading, JSON-safe cases, resuming from
earlier case files, running one case (one BLAS thread, errors caught) and the retry rule."""
from __future__ import annotations

import contextlib
import copy
import json
import os
import pickle
import sys
import time
import traceback
from collections import deque
from dataclasses import dataclass
from pathlib import Path

from pneumatics.errors import ConfigError


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


def json_default(x):
    if hasattr(x, "tolist"):  # numpy scalars and arrays
        return x.tolist()
    raise TypeError(f"{type(x).__name__} is not JSON-serialisable")


def plain_case(case, i) -> dict:
    if not isinstance(case, dict):
        raise ConfigError(f"sweep: case {i} is a {type(case).__name__}; expected a dict")
    try:
        return json.loads(json.dumps(case, default=json_default))
    except (TypeError, ValueError) as e:
        raise ConfigError(f"sweep: case {i} is not JSON-serialisable: {e}") from None


def resume_cases(out: Path, cases: list[dict]) -> list[CaseResult | None]:
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


def error_summary(e: BaseException) -> str:
    """The exception and the innermost frames: what a user needs to find the fault."""
    tb = traceback.TracebackException.from_exception(e)
    head = "".join(tb.format_exception_only()).strip()
    here = Path(__file__).parent
    stack = [f for f in tb.stack if Path(f.filename).parent != here]  # not the sweep's own frames
    frames = [f"  at {Path(f.filename).name}:{f.lineno} in {f.name}" for f in stack[-3:]][::-1]
    return "\n".join([head, *frames])


def one_thread():
    """BLAS and OpenMP limited to one thread while a case runs, on every backend: a
    multi-threaded BLAS sums in another order (results differ in the last digits) and Ray
    workers are single-threaded by default (OMP_NUM_THREADS=1); parallelism comes from the
    workers, and one thread each avoids oversubscribing the cores."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a dependency; without it, bits may differ
        return contextlib.nullcontext()
    return threadpool_limits(limits=1)


def call_case(fn, case: dict):
    """Run one case; never raises (an Exception becomes the error string)."""
    t0 = time.perf_counter()
    try:
        with one_thread():
            result = fn(case)
        if not isinstance(result, dict):
            raise TypeError(f"case function {getattr(fn, '__name__', fn)!r} returned a "
                            f"{type(result).__name__}; expected a dict")
        result, error = json.loads(json.dumps(result, default=json_default)), None
    except Exception as e:  # noqa: BLE001 - reported per case
        result, error = None, error_summary(e)
    return result, error, time.perf_counter() - t0


class Tracker:
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


def run_inline(fn, cases, tracker):
    while tracker.queue:
        i = tracker.next()
        tracker.done(i, *call_case(fn, copy.deepcopy(cases[i])))


def cpu_count() -> int:
    """CPUs this process may run on (its affinity mask; all CPUs where there is none)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def check_picklable(fn, backend):
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
