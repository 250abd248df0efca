"""The ``pneumasim`` command line: run scenarios, benchmark, list models."""
from __future__ import annotations

import argparse
import sys
import warnings

from pneumatics.errors import PneumasimError


def _cmd_run(args):
    from scenarios.common import load_scenario, run_scenario, scenario_names

    if args.list or not args.name:
        for name in scenario_names():
            print(f"{name:32s} {load_scenario(name).SUMMARY}")
        return
    run_scenario(args.name, args.out, args.fast, args.rerun, args.spawn)


def _cmd_bench(args):
    from pneumasim.bench import run_bench

    run_bench(quick=args.quick, out=args.out)


def _cmd_doctor(args):
    from rich.console import Console

    from identification.doctor import diagnose
    from identification.report import summary, write
    from pneumatics.recording import read_csv
    from pneumatics.robot import load_robot

    console = Console(stderr=True)
    robot = load_robot(args.model)
    recs = [read_csv(p) for p in args.recordings]
    holds = [read_csv(p) for p in (args.holdout or [])]
    with console.status("doctor: starting") as status:
        report = diagnose(robot, recs, holds, progress=lambda msg: status.update(f"doctor: {msg}"))
    write(report, args.out, robot)
    print(summary(report))
    print(f"report: {args.out}/report.md, {args.out}/report.json, {args.out}/doctor.rrd")


def _cmd_models(args):
    import models

    for name in models.available():
        print(name)


def build_parser() -> argparse.ArgumentParser:
    from scenarios.common import add_run_options

    parser = argparse.ArgumentParser(prog="pneumasim", description="Simulate, control and diagnose pneumatic robots.")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("run", help="run a scenario (pneumasim run --list)")
    p.add_argument("name", nargs="?", help="scenario name")
    p.add_argument("--list", action="store_true", help="list the scenarios")
    add_run_options(p)
    p.set_defaults(func=_cmd_run)
    p = sub.add_parser("bench", help="benchmark the simulation step (writes runs/bench/bench.json)")
    p.add_argument("--quick", action="store_true", help="fewer steps")
    p.add_argument("--out", default="runs/bench", help="output folder")
    p.set_defaults(func=_cmd_bench)
    p = sub.add_parser("doctor", help="find the physics a simulation left out (writes DIR/report.json, .md, .rrd)")
    p.add_argument("--model", required=True, help="model name (pneumasim models)")
    p.add_argument("recordings", nargs="+", metavar="REC.csv", help="recordings to fit")
    p.add_argument("--holdout", nargs="+", metavar="REC.csv", help="held-out recordings (default: last 30 %%)")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=_cmd_doctor)
    p = sub.add_parser("models", help="list the models")
    p.set_defaults(func=_cmd_models)
    return parser


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    warnings.simplefilter("default")
    try:
        args.func(args)
    except PneumasimError as e:
        sys.exit(f"pneumasim: error: {e}")
    except KeyboardInterrupt:
        sys.exit("pneumasim: interrupted")


if __name__ == "__main__":
    main()
