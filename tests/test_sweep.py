"""The sweep: same results in case order on every backend, crashed workers retried, resume,
failures reported, clear errors.  Ray is started once for the session (2 CPUs)."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pneumatics.errors import ConfigError, PneumasimError, UnknownNameError
from workflow.sweep import BACKENDS, sweep

CASES = [{"seed": s, "n": 2000} for s in range(6)]


def stats(case):
    """Seeded random numbers: a result that differs if a case ran with another seed.  Also
    the BLAS threads the case had: a multi-threaded BLAS sums in another order (a 3000 x 300
    least-squares solve differed in the last digits between 2 threads and Ray's 1), so every
    backend runs cases on one."""
    from threadpoolctl import threadpool_info

    x = np.random.default_rng(case["seed"]).normal(size=case["n"])
    blas = max((i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"), default=1)
    return {"seed": case["seed"], "mean": float(x.mean()), "sd": x.std(), "first": x[:3], "blas_threads": blas}


def die_once(case):
    """Kills its own worker process (SIGKILL, as the OOM killer would) the first time it runs a
    case that asks for it; the retry then succeeds."""
    flag = case.get("die_flag")
    if flag and not os.path.exists(flag):
        Path(flag).touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return stats(case)


def die_always(case):
    if case.get("always_die"):
        os.kill(os.getpid(), signal.SIGKILL)
    return stats(case)


#: cases this worker process has run (a module global: one per process)
_CASES_HERE = []


def process_memory(case):
    """The worker's pid, how many cases it ran before this one, and this case's peak resident
    memory [MiB] after it held ``mib`` MiB (Linux's VmHWM: a process's high-water mark)."""
    _CASES_HERE.append(case["seed"])
    block = np.ones(int(case.get("mib", 0)) * 2**17)  # 2**17 float64 = 1 MiB, touched
    peak = next(float(line.split()[1]) / 1024 for line in open("/proc/self/status") if line.startswith("VmHWM:"))
    del block
    return {"pid": os.getpid(), "before": len(_CASES_HERE) - 1, "peak_mib": peak}


def fail_on_three(case):
    if case["seed"] == 3:
        raise ValueError(f"seed {case['seed']} is unlucky")
    return stats(case)


def logged_slow(case):
    """Appends the seed to a log (to count computations), then takes 0.3 s."""
    with open(case["log"], "a") as f:
        f.write(f"{case['seed']}\n")
    time.sleep(0.3)
    return stats(case)


@pytest.fixture(scope="session")
def ray_local():
    ray = pytest.importorskip("ray")
    if not ray.is_initialized():
        ray.init(num_cpus=2, include_dashboard=False, logging_level="WARNING")
    yield ray
    ray.shutdown()


def test_backends_agree_in_case_order(ray_local, tmp_path):
    expected = [stats(c) for c in CASES]
    for backend in BACKENDS:
        res = sweep(stats, CASES, backend=backend, workers=2, progress=False)
        assert [r.index for r in res] == list(range(len(CASES)))
        assert [r.case for r in res] == CASES
        assert all(r.ok and r.attempts == 1 for r in res), backend
        got = [r.result for r in res]
        assert got == json.loads(json.dumps([{**e, "sd": float(e["sd"]), "first": e["first"].tolist(),
                                              "blas_threads": 1} for e in expected])), backend


@pytest.mark.parametrize("backend", ["process", "ray"])
def test_killed_worker_loses_only_its_case_which_is_retried(backend, ray_local, tmp_path):
    cases = [dict(c) for c in CASES]
    cases[2]["die_flag"] = str(tmp_path / "died")
    res = sweep(die_once, cases, out=tmp_path / "out", backend=backend, workers=2, progress=False)
    assert (tmp_path / "died").exists()  # the worker really was killed once
    assert all(r.ok for r in res)
    assert [r.attempts for r in res] == [1, 1, 2, 1, 1, 1]
    assert [r.result["mean"] for r in res] == [stats(c)["mean"] for c in cases]
    assert len(list((tmp_path / "out" / "cases").glob("*.json"))) == len(cases)


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="VmHWM is Linux's")
@pytest.mark.parametrize("backend", ["process", "ray"])
def test_fresh_workers_give_each_case_a_process_of_its_own(backend, request):
    """With fresh_workers a case's process peak is its own: a small case after a 300 MiB one
    does not inherit the large one's high-water mark, as it does in a kept worker."""
    if backend == "ray":
        request.getfixturevalue("ray_local")
    cases = [{"seed": 0, "mib": 300}] + [{"seed": s} for s in range(1, 5)]
    fresh = [r.result for r in sweep(process_memory, cases, backend=backend, workers=1, progress=False,
                                     fresh_workers=True)]
    assert len({r["pid"] for r in fresh}) == len(cases) and all(r["before"] == 0 for r in fresh)
    assert fresh[0]["peak_mib"] > 300 and max(r["peak_mib"] for r in fresh[1:]) < fresh[0]["peak_mib"] - 250
    if backend == "process":  # a kept worker runs them all, the big case's peak stays its own
        kept = [r.result for r in sweep(process_memory, cases, backend=backend, workers=1, progress=False)]
        assert len({r["pid"] for r in kept}) == 1
        assert min(r["peak_mib"] for r in kept) > 300


def test_fresh_workers_one_case_still_gets_a_worker():
    """One case is normally run inline (no pool to share); with fresh_workers it gets a worker."""
    res = sweep(process_memory, [{"seed": 9}], progress=False, fresh_workers=True)
    assert res[0].result["pid"] != os.getpid() and res[0].result["before"] == 0


def test_killed_every_time_is_reported_failed_not_dropped(tmp_path):
    cases = [dict(c) for c in CASES[:3]]
    cases[1]["always_die"] = True
    res = sweep(die_always, cases, out=tmp_path, backend="process", workers=2, retries=1, progress=False)
    assert [r.ok for r in res] == [True, False, True]
    assert res[1].attempts == 2 and res[1].result is None
    assert "died (killed by SIGKILL) while running case 1" in res[1].error
    assert json.loads((tmp_path / "sweep.json").read_text())["failed_cases"] == [1]


def test_failure_reported_after_retries_and_rerun_on_resume(tmp_path):
    out = tmp_path / "out"
    res = sweep(fail_on_three, CASES, out=out, backend="process", workers=2, retries=1, progress=False)
    bad = res[3]
    assert not bad.ok and bad.result is None and bad.attempts == 2
    assert "ValueError: seed 3 is unlucky" in bad.error and "fail_on_three" in bad.error
    assert all(r.ok for i, r in enumerate(res) if i != 3)
    saved = json.loads((out / "cases" / "3.json").read_text())
    assert saved["error"] == bad.error and saved["case"] == CASES[3]
    summary = json.loads((out / "sweep.json").read_text())
    assert summary["failed"] == 1 and summary["failed_cases"] == [3]
    # a resumed run reuses the five good cases and runs the failed one again
    res2 = sweep(stats, CASES, out=out, backend="inline", progress=False)
    assert [r.resumed for r in res2] == [True, True, True, False, True, True]
    assert all(r.ok for r in res2) and res2[3].result == sweep(stats, CASES[3:4], progress=False)[0].result


def test_interrupted_sweep_resumes_without_recomputing(tmp_path):
    out, log = tmp_path / "out", tmp_path / "calls.log"
    cases = [{"seed": s, "n": 100, "log": str(log)} for s in range(6)]
    script = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r})\n"
              "from test_sweep import logged_slow\nfrom workflow.sweep import sweep\n"
              f"sweep(logged_slow, {cases!r}, out={str(out)!r}, workers=1, progress=False)\n")
    proc = subprocess.Popen([sys.executable, "-c", script])
    deadline = time.time() + 60
    while len(list((out / "cases").glob("*.json"))) < 2 and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
    proc.kill()  # interrupt the sweep hard, mid-case
    proc.wait()
    finished = {int(p.stem) for p in (out / "cases").glob("*.json")}
    assert 2 <= len(finished) < len(cases)
    res = sweep(logged_slow, cases, out=out, backend="process", workers=2, progress=False)
    assert all(r.ok for r in res)
    assert {r.index for r in res if r.resumed} == finished
    calls = [int(x) for x in log.read_text().split()]
    assert all(calls.count(i) == 1 for i in finished)  # finished cases were not recomputed
    assert set(calls) == set(range(len(cases)))
    # a changed case dict is rerun, not skipped
    cases[0]["n"] = 101
    res = sweep(logged_slow, cases, out=out, backend="inline", progress=False)
    assert [r.resumed for r in res] == [False] + [True] * 5
    assert res[0].result["mean"] == pytest.approx(float(np.random.default_rng(0).normal(size=101).mean()))


def test_clear_errors():
    with pytest.raises(UnknownNameError, match="unknown sweep backend 'threads'; valid: inline, process, ray"):
        sweep(stats, CASES, backend="threads")
    with pytest.raises(ConfigError, match="cannot be sent to process workers"):
        sweep(lambda case: case, CASES, progress=False)
    assert sweep(lambda case: {"x": case["seed"]}, CASES[:2], backend="inline", progress=False)[1].result == {"x": 1}
    with pytest.raises(ConfigError, match="case 1 is not JSON-serialisable"):
        sweep(stats, [CASES[0], {"seed": object()}], progress=False)
    with pytest.raises(PneumasimError, match="Ray not reachable at 127.0.0.1:1"):
        sweep(stats, CASES, backend="ray", ray_address="127.0.0.1:1", progress=False)
    res = sweep(lambda case: [1], CASES[:1], backend="inline", retries=0, progress=False)
    assert "expected a dict" in res[0].error
    with pytest.raises(ConfigError, match="fresh_workers=True needs worker processes; backend 'inline'"):
        sweep(stats, CASES, backend="inline", fresh_workers=True, progress=False)


def test_fresh_workers_from_the_environment(monkeypatch):
    from workflow.sweep.api import options_from_env

    monkeypatch.setenv("PNEUMASIM_FRESH_WORKERS", "1")
    assert options_from_env()["fresh_workers"] is True
    monkeypatch.setenv("PNEUMASIM_FRESH_WORKERS", "yes")
    with pytest.raises(ConfigError, match="PNEUMASIM_FRESH_WORKERS = 'yes'; expected 1"):
        options_from_env()


def test_cli_maps_a_module_function_and_resumes(tmp_path, capsys):
    from pneumasim.cli import main

    (tmp_path / "cases.json").write_text(json.dumps(CASES[:3]))
    argv = ["sweep", "test_sweep:fail_on_three", "--cases", str(tmp_path / "cases.json"), "--out",
            str(tmp_path / "out"), "--backend", "inline", "--no-progress"]
    main(argv)
    summary = json.loads(capsys.readouterr().out)
    assert summary["cases"] == 3 and summary["failed"] == 0 and summary["resumed"] == 0
    rows = json.loads((tmp_path / "out" / "results.json").read_text())
    assert [r["result"]["seed"] for r in rows] == [0, 1, 2]
    main(argv)
    assert json.loads(capsys.readouterr().out)["resumed"] == 3
    (tmp_path / "cases.json").write_text(json.dumps(CASES))  # seed 3 fails: exit status 1
    with pytest.raises(SystemExit, match=r"1 case\(s\) failed: \[3\]"):
        main(argv)


def test_domain_sweep_fast_tracks_worse_with_less_air(tmp_path, monkeypatch):
    """arm2_domain_sweep --fast (inline: the pytest process's compiled kernel is reused): less
    supply pressure or smaller valves mean less flow to the chambers and worse tracking.
    Slow-marked only for the first-step numba compilation of the kernel (50-75 s on the
    loaded machine when this file runs alone); with the kernel compiled it takes ~3 s."""
    from scenarios.common import run_scenario

    monkeypatch.setenv("PNEUMASIM_BACKEND", "inline")
    m = run_scenario("arm2_domain_sweep", tmp_path, fast=True, quiet=True)
    assert m["cases"] == 4 and m["failed"] == 0
    grid = json.loads((tmp_path / "grid.json").read_text())
    err = np.array(grid["rms_error_deg"])  # rows: supply 4, 7 bar; columns: area scale 0.5, 1
    assert grid["supply_bar"] == [4.0, 7.0] and grid["area_scale"] == [0.5, 1.0]
    assert np.all(err[0] > err[1]) and np.all(err[:, 0] > err[:, 1])
    assert m["rms_error_deg_min"] == m["rms_error_deg_nominal"] == err[1, 1] < 5.0
    assert (tmp_path / "tracking_error_map.png").stat().st_size > 10_000
    again = run_scenario("arm2_domain_sweep", tmp_path, fast=True, quiet=True)  # resumed from sweep/cases
    assert json.loads((tmp_path / "sweep" / "sweep.json").read_text())["resumed"] == 4
    assert {k: v for k, v in again.items() if k != "wall_seconds"} == {k: v for k, v in m.items() if k != "wall_seconds"}
