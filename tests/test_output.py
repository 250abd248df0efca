"""The output discipline (pneumatics/io.py): --out checked before any work, results swapped
in whole, interrupted runs leave the previous results byte-identical, files follow the umask;
progress lines without a terminal; "did you mean" for misspelt names."""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pneumatics.errors import OutputError, UnknownNameError
from pneumatics.io import MARKER, OutputFolder, atomic_write_text, remove_abandoned

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data"
TIMESTAMPED = re.compile(r"^\d\d:\d\d:\d\d \+\d+\.\d s ")


def _env(**extra) -> dict:
    env = dict(os.environ, PYTHONPATH=str(ROOT), PNEUMASIM_PROGRESS="plain", **extra)
    return env


def _cli(args, cwd, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pneumasim.cli", *map(str, args)], cwd=cwd, env=_env(),
                          capture_output=True, text=True, **kw)


def _snapshot(*paths: Path) -> dict:
    """Every file under ``paths`` (and the paths themselves if files): name -> bytes."""
    files = {}
    for p in paths:
        for f in ([p] if p.is_file() else sorted(p.rglob("*"))):
            if f.is_file():
                files[str(f)] = f.read_bytes()
    return files


def _leftovers(parent: Path) -> list[str]:
    return sorted(p.name for p in parent.iterdir() if ".partial" in p.name or ".old-" in p.name)


# ---------------------------------------------------------------- the folder, in-process

def test_a_finished_run_replaces_the_folder_whole_without_stale_files(tmp_path):
    target = tmp_path / "report"
    with OutputFolder(target) as out:
        (out.path / "report.json").write_text("{}")
        (out.path / "finding_1.png").write_text("old picture")
    with OutputFolder(target) as out:
        (out.path / "report.json").write_text('{"findings": []}')
    assert sorted(p.name for p in target.iterdir()) == [MARKER, "report.json"]  # finding_1.png gone
    assert (target / "report.json").read_text() == '{"findings": []}'
    assert _leftovers(tmp_path) == []


def test_paths_a_run_stores_name_the_final_folder(tmp_path):
    target = tmp_path / "demo"
    with OutputFolder(target) as out:
        rec = out.path / "doctor_case" / "mystery.csv"
        rec.parent.mkdir()
        rec.write_text("time\n0\n")
        atomic_write_text(out.path / "report.json", json.dumps({"source": str(rec)}))
    assert json.loads((target / "report.json").read_text())["source"] == str(target / "doctor_case" / "mystery.csv")


def test_a_failed_run_leaves_the_previous_results_and_no_staging_folder(tmp_path):
    target = tmp_path / "report"
    with OutputFolder(target) as out:
        (out.path / "report.json").write_text("first")
        (out.path / "report.md").write_text("first")
    before = _snapshot(target)
    with pytest.raises(RuntimeError):
        with OutputFolder(target) as out:
            (out.path / "report.json").write_text("second")
            raise RuntimeError("the doctor failed while writing")
    assert _snapshot(target) == before and _leftovers(tmp_path) == []


def test_out_is_checked_before_any_work(tmp_path):
    (tmp_path / "afile").write_text("x")
    with pytest.raises(OutputError, match="--out .*afile: is a file; expected a folder"):
        OutputFolder(tmp_path / "afile")
    with pytest.raises(OutputError, match="afile is a file, not a folder"):
        OutputFolder(tmp_path / "afile" / "sub")
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "rec.csv").write_text("time\n0\n")
    with pytest.raises(OutputError, match="holds the input .*rec.csv; the results replace the whole folder"):
        OutputFolder(tmp_path / "data", inputs=[tmp_path / "data" / "rec.csv"])
    (tmp_path / "data" / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match=r"holds files pneumasim did not write \(notes.txt, rec.csv\)"):
        OutputFolder(tmp_path / "data")
    with pytest.raises(OutputError, match="is the current or home folder"):
        OutputFolder(Path.cwd())


def test_a_killed_runs_staging_folder_is_removed_by_the_next_run(tmp_path):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".report.partial-{dead.pid}-abc"
    stale.mkdir()
    (stale / "half.json").write_text("{")
    alive = tmp_path / f".report.partial-{os.getpid()}-def"  # a run still going: kept
    alive.mkdir()
    remove_abandoned(tmp_path / "report")
    assert not stale.exists() and alive.exists()


def test_files_follow_the_umask(tmp_path):
    old = os.umask(0o027)
    try:
        atomic_write_text(tmp_path / "a.json", "{}")
        with OutputFolder(tmp_path / "out") as out:
            (out.path / "b.txt").write_text("b")
    finally:
        os.umask(old)
    assert (tmp_path / "a.json").stat().st_mode & 0o777 == 0o640  # was 0600 (mkstemp)
    assert (tmp_path / "out").stat().st_mode & 0o777 == 0o750  # was 0700 (mkdtemp)


def test_progress_is_plain_timestamped_lines_without_a_terminal(capsys, monkeypatch):
    from workflow.progress import Progress, progress_mode

    monkeypatch.delenv("PNEUMASIM_PROGRESS", raising=False)
    assert progress_mode() == "plain"  # pytest captures stderr: not a terminal
    with Progress("doctor humanoid38") as p:
        p.say("calibrating chambers")
        p("scoring hypotheses")  # also a progress(msg) callback
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 2 and all(TIMESTAMPED.match(line) for line in lines)
    assert lines[1].endswith("doctor humanoid38: scoring hypotheses")
    monkeypatch.setenv("PNEUMASIM_PROGRESS", "none")
    with Progress("doctor") as p:
        p.say("quiet")
    assert capsys.readouterr().err == ""


# ---------------------------------------------------------------- the commands

def _bench_recording(folder: Path) -> Path:
    from test_bench_doctor import _cyl_rec

    path = folder / "r.csv"
    _cyl_rec(3, 6.0, 0.0, duration=20.0).to_csv(path)
    return path


def _all_modes(folder: Path) -> set:
    return {p.stat().st_mode & 0o777 for p in [folder, *folder.rglob("*")]}


def test_doctor_output_umask_022_gives_0644_and_a_progress_line_per_stage(tmp_path):
    rec = _bench_recording(tmp_path)
    r = _cli(["doctor", "--model", "bench_cylinder", rec, "--out", tmp_path / "d"], tmp_path, umask=0o022)
    assert r.returncode == 0, r.stderr
    assert _all_modes(tmp_path / "d") == {0o755, 0o644}
    stages = [line for line in r.stderr.splitlines() if TIMESTAMPED.match(line)]
    assert [s.split(": ", 1)[1] for s in stages] == [
        "reading 1 recording(s)",
        "fitting the cylinder's friction models and checking them on held-out data",
        "writing the report"]
    assert all("doctor bench_cylinder" in s for s in stages)


def test_doctor_refuses_an_unwritable_out_before_reading_anything(tmp_path):
    (tmp_path / "afile").write_text("x")
    r = _cli(["doctor", "--model", "bench_cylinder", "missing.csv", "--out", tmp_path / "afile"], tmp_path)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert r.stderr.strip() == (f"pneumasim: error: --out {tmp_path / 'afile'}: is a file; expected a folder "
                                "(it is replaced whole by the results)")


def test_bench_checks_out_before_benchmarking(tmp_path):
    (tmp_path / "afile").write_text("x")
    t0 = time.perf_counter()
    r = _cli(["bench", "--quick", "--out", tmp_path / "afile"], tmp_path)
    assert r.returncode == 1 and "--out" in r.stderr and "is a file; expected a folder" in r.stderr
    assert time.perf_counter() - t0 < 60  # no benchmark ran (the quick one takes minutes)


def test_a_symlinked_out_is_replaced_where_it_points(tmp_path):
    with OutputFolder(tmp_path / "real") as out:
        (out.path / "metrics.json").write_text("1")
    (tmp_path / "link").symlink_to(tmp_path / "real")
    with OutputFolder(tmp_path / "link") as out:
        (out.path / "metrics.json").write_text("2")
    assert (tmp_path / "link").is_symlink() and (tmp_path / "link" / "metrics.json").read_text() == "2"
    assert _leftovers(tmp_path) == []


def test_doctor_refuses_a_read_only_folder(tmp_path):
    """A read-only parent and a read-only --out (chmod; root may write there, so as root a
    place even root cannot write: sysfs)."""
    if os.geteuid() == 0:
        r = _cli(["doctor", "--model", "bench_cylinder", "r.csv", "--out", "/sys/pneumasim-results"], tmp_path)
        assert r.returncode == 1 and r.stderr.strip() == ("pneumasim: error: --out /sys/pneumasim-results: cannot "
                                                          "write beside it in /sys (Operation not permitted)")
        return
    (tmp_path / "ro").mkdir()
    (tmp_path / "ro" / "report.json").write_text("{}")
    os.chmod(tmp_path / "ro", 0o555)
    try:
        for out, why in ((tmp_path / "ro" / "new", f"cannot create files in {tmp_path / 'ro'}"),
                         (tmp_path / "ro", "the folder is read-only")):
            r = _cli(["doctor", "--model", "bench_cylinder", "r.csv", "--out", out], tmp_path)
            assert r.returncode == 1 and "Traceback" not in r.stderr and why in r.stderr, r.stderr
    finally:
        os.chmod(tmp_path / "ro", 0o755)


def _kill_when(proc: subprocess.Popen, ready, sig, timeout=120.0):
    t0 = time.time()
    while not ready():
        assert proc.poll() is None, "the run finished before it could be interrupted"
        assert time.time() - t0 < timeout
        time.sleep(0.02)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    if sig != signal.SIGKILL:  # one line, whatever the run was doing (an import, a fit, the writing)
        assert "Traceback" not in err and err.rstrip().endswith("interrupted; the previous results are unchanged"), err
    return proc.returncode


def _popen(args, cwd):
    # Ctrl-C's default action in the child even when the tests run as a background job (a shell
    # without job control starts those with SIGINT ignored, and a child inherits that)
    return subprocess.Popen([sys.executable, "-m", "pneumasim.cli", *map(str, args)], cwd=cwd, env=_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, umask=0o022,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _staging(parent: Path, name: str):
    found = [p for p in parent.glob(f".{name}.partial-*") if p.is_dir()]
    return found[0] if found else None


_SWALLOWED_STOP = """
import os, signal, sys, weakref
from pneumatics.io import OutputFolder
from pneumatics.stopping import stops_cleanly
with stops_cleanly("t: "):
    with OutputFolder(sys.argv[1]) as out:
        (out.path / "x.txt").write_text("new")
        class Held: pass
        held = Held()
        # Ctrl-C handled inside a weakref callback: Python prints the KeyboardInterrupt and goes on
        ref = weakref.ref(held, lambda _: (os.kill(os.getpid(), signal.SIGINT), sum(range(1000))))
        del held
        print("the block went on")
"""


def test_a_stop_python_swallowed_still_leaves_the_previous_results_and_ends_by_sigint(tmp_path):
    with OutputFolder(tmp_path / "out") as out:
        (out.path / "x.txt").write_text("old")
    r = subprocess.run([sys.executable, "-c", _SWALLOWED_STOP, tmp_path / "out"], env=_env(), capture_output=True,
                       text=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert "Exception ignored" in r.stderr and r.stdout == "the block went on\n"  # the case this covers
    assert r.returncode == -signal.SIGINT and r.stderr.rstrip().endswith("t: interrupted; the previous results are unchanged")
    assert (tmp_path / "out" / "x.txt").read_text() == "old" and _leftovers(tmp_path) == []


def test_doctor_interrupted_or_killed_leaves_the_previous_report_byte_identical(tmp_path):
    rec = _bench_recording(tmp_path)
    args = ["doctor", "--model", "bench_cylinder", rec, "--out", tmp_path / "d"]
    assert _cli(args, tmp_path).returncode == 0
    before = _snapshot(tmp_path / "d")
    assert len(before) == 4  # report.json, report.md, friction_fit.png, the marker
    for sig in (signal.SIGINT, signal.SIGKILL):
        proc = _popen(args, tmp_path)
        code = _kill_when(proc, lambda: _staging(tmp_path, "d") is not None, sig)
        assert code == -sig  # ended by the signal, as Ctrl-C's convention asks
        assert _snapshot(tmp_path / "d") == before
    assert _cli(args, tmp_path).returncode == 0  # the next run clears the killed run's staging folder
    assert _leftovers(tmp_path) == []


@pytest.mark.slow
def test_scenario_interrupted_or_killed_leaves_results_and_rrd_byte_identical(tmp_path):
    """sarcos_locked --fast (~10 s, writes a CSV per pressure as it goes) with --rerun outside
    --out: stopped once the staging folder holds its first recording."""
    out, rrd = tmp_path / "locked", tmp_path / "rrd" / "locked.rrd"
    args = ["run", "sarcos_locked", "--fast", "--out", out, "--rerun", rrd]
    first = _cli(args, tmp_path, umask=0o022)
    assert first.returncode == 0, first.stderr
    assert re.search(r"scenario sarcos_locked: started \(--fast\)", first.stderr)
    assert re.search(r"scenario sarcos_locked: finished in [\d.]+ s", first.stderr)
    assert _all_modes(out) == {0o755, 0o644} and rrd.stat().st_mode & 0o777 == 0o644
    before = _snapshot(out, rrd)
    for sig in (signal.SIGINT, signal.SIGKILL):
        proc = _popen(args, tmp_path)

        def started():
            staging = _staging(tmp_path, "locked")
            return staging is not None and any(staging.glob("*.csv"))

        code = _kill_when(proc, started, sig)
        assert code == -sig  # ended by the signal, as Ctrl-C's convention asks
        assert _snapshot(out, rrd) == before
        if sig == signal.SIGINT:
            assert _leftovers(tmp_path) == [] and _leftovers(rrd.parent) == []


@pytest.mark.slow
def test_arm2_doctor_killed_mid_diagnosis_leaves_the_previous_report(tmp_path):
    from scenarios._cases import make_case

    truth = make_case(tmp_path / "case", 5, ["coulomb_friction"], seconds=10.0, heldout_seconds=5.0, name="small")
    args = ["doctor", "--model", "arm2", truth["recordings"]["main"], "--holdout", truth["recordings"]["heldout"],
            "--out", tmp_path / "d"]
    assert _cli(args, tmp_path).returncode == 0
    before = _snapshot(tmp_path / "d")
    assert {Path(p).name for p in before} >= {"report.json", "report.md", "doctor.rrd"}
    for sig in (signal.SIGINT, signal.SIGKILL):
        proc = _popen(args, tmp_path)
        lines = []

        def calibrating():  # stderr is read line by line: the stage lines come as they happen
            lines.append(proc.stderr.readline())
            return "calibrating chambers" in lines[-1]

        code = _kill_when(proc, calibrating, sig)
        assert code == -sig  # ended by the signal, as Ctrl-C's convention asks
        assert _snapshot(tmp_path / "d") == before


def test_import_refuses_its_source_and_a_json_out_and_writes_the_pair(tmp_path):
    src = tmp_path / "friction.csv"
    src.write_bytes((DATA / "zillen_friction_slice.csv").read_bytes())
    base = ["import", src, "--map", "zillen_friction"]
    r = _cli([*base, "--out", src], tmp_path)
    assert r.returncode == 1 and f"--out {src}: is the input {src}; writing it would destroy the input" in r.stderr
    r = _cli([*base, "--out", tmp_path / "rec.json"], tmp_path)
    assert r.returncode == 1 and "a recording is a CSV file and its metadata goes to a sidecar" in r.stderr
    assert src.read_bytes() == (DATA / "zillen_friction_slice.csv").read_bytes()
    log = tmp_path / "log.json"  # a log whose name the sidecar of log.csv would take
    log.write_bytes(src.read_bytes())
    r = _cli(["import", log, "--map", "zillen_friction", "--out", tmp_path / "log.csv"], tmp_path)
    assert r.returncode == 1 and not (tmp_path / "log.csv").exists()
    assert f"--out {tmp_path / 'log.csv'}: its sidecar {log} would overwrite the input {log}" in r.stderr
    r = _cli([*base, "--out", tmp_path / "rec.csv"], tmp_path, umask=0o022)
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "rec.json").read_text())["model"] == "bench_cylinder"
    assert {(tmp_path / f).stat().st_mode & 0o777 for f in ("rec.csv", "rec.json")} == {0o644}
    before = _snapshot(tmp_path / "rec.csv", tmp_path / "rec.json")
    r = _cli(["import", DATA / "zillen_chamber_slice.csv", "--map", "zillen_friction", "--out", tmp_path / "rec.csv"],
             tmp_path)  # the wrong map: fails while reading; the previous pair stays
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert _snapshot(tmp_path / "rec.csv", tmp_path / "rec.json") == before and _leftovers(tmp_path) == []


CASES_MODULE = '''
import os, signal

def square(case):
    if case["x"] == int(os.environ.get("DIE_AT", "-1")):
        os.kill(os.getpid(), signal.SIGKILL)   # the whole sweep dies mid-way
    return {"y": case["x"] ** 2}
'''


def test_sweep_killed_keeps_its_finished_cases_and_the_previous_complete_sweep(tmp_path):
    (tmp_path / "cases_mod.py").write_text(CASES_MODULE)
    (tmp_path / "a.json").write_text(json.dumps([{"x": x} for x in range(4)]))
    (tmp_path / "b.json").write_text(json.dumps([{"x": x} for x in range(6)]))
    args = ["sweep", "cases_mod:square", "--backend", "inline", "--out", tmp_path / "out"]
    r = _cli([*args, "--cases", tmp_path / "a.json"], tmp_path)
    assert r.returncode == 0, r.stderr
    assert re.search(r"sweep square: 4/4 done, 0 failed, 0 retries$", r.stderr, re.M)
    before = _snapshot(tmp_path / "out")
    env = _env(DIE_AT="5")
    r = subprocess.run([sys.executable, "-m", "pneumasim.cli", *map(str, args), "--cases", tmp_path / "b.json"],
                       cwd=tmp_path, env=env, capture_output=True, text=True)
    assert r.returncode == -9
    assert _snapshot(tmp_path / "out") == before  # the complete sweep a.json made, untouched
    partial = tmp_path / ".out.partial"
    assert sorted(p.name for p in (partial / "cases").iterdir()) == [f"{i}.json" for i in range(5)]
    r = _cli([*args, "--cases", tmp_path / "b.json"], tmp_path)
    assert r.returncode == 0, r.stderr
    summary = json.loads(r.stdout)
    assert summary["cases"] == 6 and summary["resumed"] == 5 and not partial.exists()
    rows = json.loads((tmp_path / "out" / "results.json").read_text())
    assert [row["result"]["y"] for row in rows] == [x * x for x in range(6)]


# ---------------------------------------------------------------- did you mean

def test_misspelt_names_get_a_did_you_mean():
    from pneumatics.importer import load_map
    from pneumatics.robot import load_robot
    from scenarios._cases import draw_effect
    from scenarios.common import load_scenario

    import numpy as np

    for call, hint in ((lambda: load_scenario("arm2_step_respons"), "did you mean 'arm2_step_response'"),
                       (lambda: load_robot("humanoid83"), "did you mean 'humanoid38'?"),
                       (lambda: load_map("zillen_frction"), "did you mean 'zillen_friction'?"),
                       (lambda: draw_effect("valve_hysteresiss", np.random.default_rng(0)),
                        "did you mean 'valve_hysteresis'?")):
        with pytest.raises(UnknownNameError, match=re.escape(hint)):
            call()
    with pytest.raises(UnknownNameError) as e:
        load_scenario("zzzz")
    assert "did you mean" not in str(e.value) and "; valid: arm2_" in str(e.value)


def test_cli_run_typo_is_one_line_with_a_suggestion(tmp_path):
    r = _cli(["run", "sarcos_lockd"], tmp_path)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert r.stderr.startswith("pneumasim: error: unknown scenario 'sarcos_lockd'; did you mean 'sarcos_locked'")
