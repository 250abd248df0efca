"""What every scenario shares: command-line options, the output folder, metrics and plots.

A scenario module defines ``SUMMARY`` (one line) and ``run(ctx: Context) -> dict`` returning
its metrics; ``python -m scenarios.<name>`` and ``pneumasim run <name>`` both go through
:func:`main`.  One that sets ``FITTED_MODEL = "<robot>"`` and loads that robot with
``ctx.load_robot`` takes ``--fitted MODEL.toml`` (a doctor's fitted model of that robot).
"""
from __future__ import annotations

import argparse
import importlib
import json
import math
import pkgutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from pneumatics.errors import PneumasimError, UnknownNameError  # noqa: E402
from pneumatics.io import OutputFolder, atomic_save, atomic_write_json  # noqa: E402
from workflow.progress import Progress  # noqa: E402
from pneumatics.stopping import stops_cleanly  # noqa: E402


@dataclass
class Context:
    """Where a scenario writes and how long it may take.

    ``out`` is the staging folder of the run (pneumatics.io.OutputFolder), swapped in at
    ``final_out`` when the scenario has finished; ``rerun_path`` likewise a temporary name
    moved into place at the end.  Messages name files by :meth:`shown`."""

    name: str
    out: Path
    fast: bool = False
    rerun_path: Path | None = None
    spawn: bool = False
    written: list[Path] = field(default_factory=list)
    final_out: Path | None = None
    fitted: Path | None = None      # a doctor's model.toml (--fitted): ctx.load_robot loads it

    def shown(self, path: str | Path) -> Path:
        """Where ``path`` (written under ``out``) will be once the run has finished."""
        path = Path(path)
        if self.final_out is None or not path.is_relative_to(self.out):
            return path
        return self.final_out / path.relative_to(self.out)

    def load_robot(self, name: str, **kwargs):
        """``pneumatics.robot.load_robot(name)``, with the run's fitted model if one was given
        (run_scenario has checked that it was fitted to the scenario's FITTED_MODEL)."""
        from pneumatics.robot import load_robot

        return load_robot(name, fitted=self.fitted, **kwargs)

    def rerun_logger(self, robot, recording_name: str | None = None):
        """A Rerun logger if ``--rerun``/``--spawn`` was given, else None."""
        if self.rerun_path is None and not self.spawn:
            return None
        from workflow.rerun_log import RerunLogger

        if self.rerun_path is not None:  # a fresh file: the staging folder may share it with the last run
            self.rerun_path.unlink(missing_ok=True)

        return RerunLogger(robot, path=self.rerun_path, spawn=self.spawn,
                           recording_name=recording_name or self.name)

    def savefig(self, fig, filename: str) -> Path:
        path = self.out / filename
        atomic_save(path, lambda tmp: fig.savefig(tmp, dpi=110, bbox_inches="tight"))
        plt.close(fig)
        self.written.append(path)
        return path

    def save_recording(self, rec, filename: str) -> Path:
        path = self.out / filename
        rec.to_csv(path)
        self.written.append(path)
        return path


def scenario_names() -> list[str]:
    import scenarios

    return sorted(m.name for m in pkgutil.iter_modules(scenarios.__path__)
                  if not m.name.startswith("_") and m.name != "common")


def load_scenario(name: str):
    if name not in scenario_names():
        raise UnknownNameError("scenario", name, scenario_names())
    return importlib.import_module(f"scenarios.{name}")


def clean_metrics(metrics: dict, name: str) -> dict:
    out = {}
    for k, v in metrics.items():
        if isinstance(v, bool):
            v = int(v)
        if isinstance(v, (int, float)):
            if not math.isfinite(float(v)):
                raise PneumasimError(f"scenario {name}: metric {k!r} is {v}: not finite")
            out[k] = float(v) if isinstance(v, float) else v
        elif isinstance(v, str):
            out[k] = v
        else:
            out[k] = float(v)  # numpy scalars
    return out


def fitted_scenarios() -> list[str]:
    """The scenarios that simulate a robot a fitted model can replace (their FITTED_MODEL)."""
    return [n for n in scenario_names() if getattr(load_scenario(n), "FITTED_MODEL", None)]


def check_fitted(module, name: str, fitted: Path):
    """A fitted model for scenario ``name``: the scenario must take one (``FITTED_MODEL``, the
    robot it simulates) and the file must be fitted to that robot."""
    from pneumatics.fitted_model import read_fitted

    robot = getattr(module, "FITTED_MODEL", None)
    if robot is None:
        raise PneumasimError(f"scenario {name} does not take --fitted; scenarios that do: "
                             f"{', '.join(f'{n} ({load_scenario(n).FITTED_MODEL})' for n in fitted_scenarios())}")
    fm = read_fitted(fitted)
    if fm.model != robot:
        raise PneumasimError(f"{fitted}: fitted to model {fm.model!r}, but scenario {name} simulates {robot!r}")


def run_scenario(name: str, out: str | Path | None = None, fast: bool = False,
                 rerun: str | Path | None = None, spawn: bool = False, quiet: bool = False,
                 fitted: str | Path | None = None) -> dict:
    """Run scenario ``name``; writes ``metrics.json`` and its plots into ``out``.  ``fitted``: a
    model.toml of ``pneumasim doctor`` the scenario simulates instead of the nominal robot.

    ``out`` (and the ``rerun`` file) are checked before the scenario starts and replaced only
    when it has finished (pneumatics.io.OutputFolder): a failed or interrupted run leaves the
    previous results as they were.  A scenario that sets ``RESUMABLE = True`` (its sweeps keep
    per-case files) keeps its unfinished staging folder for the next run to resume from."""
    module = load_scenario(name)
    if fitted:
        check_fitted(module, name, Path(fitted))
    target = Path(out) if out else Path("runs") / name
    with OutputFolder(target, resumable=getattr(module, "RESUMABLE", False)) as folder:
        ctx = Context(name, folder.path, fast, folder.file(rerun) if rerun else None, spawn, final_out=target,
                      fitted=Path(fitted) if fitted else None)
        with Progress(f"scenario {name}", live=False, mode="none" if quiet else None) as progress:
            progress.say(f"started{' (--fast)' if fast else ''}; results into {target}")
            t0 = time.perf_counter()
            metrics = clean_metrics(module.run(ctx), name)
            metrics.setdefault("wall_seconds", round(time.perf_counter() - t0, 2))
            if fitted:
                metrics["fitted_model"] = str(fitted)
            atomic_write_json(folder.path / "metrics.json", metrics)
            rerun_written = ctx.rerun_path is not None and ctx.rerun_path.exists()
            progress.say(f"finished in {time.perf_counter() - t0:.1f} s")
    if not quiet:
        print(f"{name}: wrote {target / 'metrics.json'}" + "".join(f", {p.name}" for p in ctx.written))
        if rerun_written:
            print(f"{name}: Rerun recording {rerun or ctx.shown(ctx.rerun_path)}")
        elif ctx.rerun_path:
            print(f"{name}: this scenario logs nothing to Rerun (its results are the PNGs and metrics)")
        print(json.dumps(metrics, indent=1))
    return metrics


def add_run_options(parser: argparse.ArgumentParser):
    parser.add_argument("--out", help="output folder (default runs/<name>/)")
    parser.add_argument("--fast", action="store_true", help="shortened version (used by the tests)")
    parser.add_argument("--rerun", metavar="FILE.rrd", help="log the run to a Rerun file")
    parser.add_argument("--spawn", action="store_true", help="log the run to a live Rerun viewer")
    parser.add_argument("--fitted", metavar="MODEL.toml",
                        help="simulate the model a doctor run fitted (its model.toml) instead of the nominal one")


def main(module_name: str, argv=None):
    """Entry point of ``python -m scenarios.<name>``."""
    if module_name == "__main__":  # python -m scenarios.<name>
        module_name = sys.modules["__main__"].__spec__.name
    name = module_name.rsplit(".", 1)[-1]
    module = load_scenario(name)
    parser = argparse.ArgumentParser(prog=f"python -m scenarios.{name}", description=module.SUMMARY)
    add_run_options(parser)
    args = parser.parse_args(argv)
    with stops_cleanly(""):  # Ctrl-C or SIGTERM: clean up, say so, end by the signal
        try:
            run_scenario(name, args.out, args.fast, args.rerun, args.spawn, fitted=args.fitted)
        except PneumasimError as e:
            sys.exit(f"error: {e}")
