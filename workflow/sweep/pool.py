"""The local process pool: workers started from a clean forkserver, kept warm between sweeps
(imports and numba compilation paid once), a dead worker replaced and its case retried."""
from __future__ import annotations

import atexit
import pickle
import signal
import sys
import time
import types

from .cases import call_case, error_summary


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
            reply = (index, *call_case(fns[fn_bytes], case))
        except Exception as e:  # noqa: BLE001 - e.g. the function's module does not import here
            reply = (index, None, "could not load the case function in the worker: " + error_summary(e), 0.0)
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
        self.cases_sent = 0

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

    def replace(self, w: _Worker, timeout: float = 0.1) -> _Worker:
        """A new worker in place of ``w``: a dead one, or a live idle one asked to stop (killed
        after ``timeout`` s)."""
        w.stop(timeout)
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


def run_process(fn, cases, tracker, n_workers, fresh_workers=False):
    """Run the tracker's cases on ``n_workers`` pool workers; with ``fresh_workers`` a worker
    that finished a case is stopped and a new one takes its place."""
    from multiprocessing.connection import wait

    fn_bytes = pickle.dumps(fn)
    preload = [m for m in ("workflow.sweep.pool", getattr(fn, "__module__", None)) if m and m != "__main__"]
    idle = list(_POOL.take(n_workers, preload, need_main=getattr(fn, "__module__", None) == "__main__"))
    if fresh_workers:  # a worker kept from an earlier sweep is not fresh
        idle = [_POOL.replace(w, timeout=2.0) if w.cases_sent else w for w in idle]
    busy: dict = {}  # conn or sentinel -> worker
    try:
        while tracker.queue or busy:
            while idle and tracker.queue:
                w = idle.pop()
                i = tracker.next()
                w.index, w.started = i, time.perf_counter()
                w.cases_sent += 1
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
                    # replaced only for a case still to run: a fresh sweep replaces a used worker first
                    idle.append(_POOL.replace(w, timeout=2.0) if fresh_workers and tracker.queue else w)
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
