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
from .api import BACKENDS, options_from_env, raise_on_failure, sweep
from .cases import CaseResult, cpu_count, load_function, read_cases
from .pool import shutdown_pool
from .ray_backend import connect_ray

__all__ = ["BACKENDS", "CaseResult", "connect_ray", "cpu_count", "load_function", "options_from_env",
           "raise_on_failure", "read_cases", "shutdown_pool", "sweep"]
