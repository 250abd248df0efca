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
    run_scenario(args.name, args.out, args.fast, args.rerun, args.spawn, fitted=args.fitted)


def _cmd_bench(args):
    from pneumasim.bench import run_bench

    run_bench(quick=args.quick, out=args.out, scaling=args.scaling)


def _cmd_doctor(args):
    """Every model kind through one entry (identification.doctor): the output folder checked
    first, stages shown, the report swapped in whole."""
    from identification.doctor import diagnose, kind_of, summary, write
    from pneumatics.io import OutputFolder
    from workflow.progress import Progress

    kind_of(args.model)  # an unknown model, or one without a doctor, fails here before any work
    folder = OutputFolder(args.out, inputs=[*args.recordings, *(args.holdout or [])])
    with folder, Progress(f"doctor {args.model}") as progress:
        recs, holds = recordings_from_args(args, progress)
        report = diagnose(args.model, recs, holds, progress=progress)
        progress.say("writing the report")
        write(report, folder.path)
        files = sorted(p.name for p in folder.path.iterdir() if p.suffix in (".md", ".json", ".rrd", ".toml", ".xml"))
    print(summary(report))
    print("report: " + ", ".join(f"{args.out}/{name}" for name in files if name not in ("model.toml", "fitted.xml")))
    if "model.toml" in files:
        print(f"the model as fitted: {args.out}/model.toml (pneumasim run SCENARIO --fitted), "
              f"{args.out}/fitted.xml (MuJoCo)")


def recordings_from_args(args, progress=None):
    """The doctor's recordings and held-out recordings, each by its suffix (CSV, Parquet, or a
    ROS bag read through --map); with ``--gauge`` the room pressure [Pa] (the sidecar's
    room_pa, else the model's) is added to every p_a./p_b. column."""
    from identification.doctor import room_pressure_pa
    from pneumatics.formats.by_suffix import read_recording
    from pneumatics.formats.rosbag import is_ros_bag
    from pneumatics.recording_checks import add_room_pressure

    room_pa = room_pressure_pa(args.model) if args.gauge else None  # builds the model: only when needed

    def read(path):
        rec = read_recording(path, args.map if is_ros_bag(path) else None)
        return add_room_pressure(rec, float(rec.meta.get("room_pa", room_pa))) if args.gauge else rec

    if progress is not None:
        progress.say(f"reading {len(args.recordings) + len(args.holdout or [])} recording(s)")
    return [read(p) for p in args.recordings], [read(p) for p in (args.holdout or [])]


def _cmd_import(args):
    from pneumatics.formats.by_suffix import import_recording
    from pneumatics.importer import sidecar_path

    meta = {}
    for item in args.meta or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise PneumasimError(f"--meta {item!r}: expected KEY=VALUE")
        try:
            meta[key] = float(value)
        except ValueError:
            meta[key] = value
    rec = import_recording(args.src, args.map, args.out, meta)
    side = f" and {sidecar_path(args.out)}" if str(args.out).lower().endswith(".csv") else ""
    print(f"import: {args.src} -> {args.out}{side} ({len(rec)} rows, "
          f"{rec.time[-1] - rec.time[0]:.1f} s; columns {', '.join(rec.columns)})")


def _cmd_sweep(args):
    import json
    import os
    import time

    from pneumatics.io import OutputFolder, atomic_write_json
    from workflow.sweep import load_function, read_cases, sweep

    if ":" not in args.target:  # a scenario: its sweeps take the options from the environment
        from scenarios.common import run_scenario

        for key, value in (("PNEUMASIM_WORKERS", args.workers), ("PNEUMASIM_RAY", args.ray),
                           ("PNEUMASIM_BACKEND", args.backend)):
            if value is not None:
                os.environ[key] = str(value)
        run_scenario(args.target, args.out, args.fast)
        return
    if not args.cases or not args.out:
        raise PneumasimError("sweep MODULE:FUNCTION needs --cases CASES.json and --out DIR")
    # resumable: an interrupted sweep keeps its finished cases beside --out for the next run
    with OutputFolder(args.out, inputs=[args.cases], resumable=True) as folder:
        fn, cases = load_function(args.target), read_cases(args.cases)
        t0 = time.perf_counter()
        results = sweep(fn, cases, out=folder.path, backend=args.backend or ("ray" if args.ray else "process"),
                        workers=args.workers, ray_address=None if args.ray in (None, "local") else args.ray,
                        retries=args.retries, progress=not args.no_progress)
        rows = [{"index": r.index, "case": r.case, "result": r.result, "error": r.error, "seconds": r.seconds,
                 "attempts": r.attempts, "resumed": r.resumed} for r in results]
        atomic_write_json(folder.path / "results.json", rows)
    path = os.path.join(args.out, "results.json")
    failed = [r.index for r in results if not r.ok]
    print(json.dumps({"cases": len(results), "failed": len(failed), "resumed": sum(r.resumed for r in results),
                      "wall_seconds": round(time.perf_counter() - t0, 2), "results": path}))
    if failed:
        sys.exit(f"pneumasim: {len(failed)} case(s) failed: {failed[:20]} (errors in {path})")


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
    p.add_argument("--scaling", action="store_true",
                   help="also the cost per step against the number of chambers (up to 200) and the doctor's "
                        "time against the recording length (scaling.png; a few minutes)")
    p.set_defaults(func=_cmd_bench)
    p = sub.add_parser("doctor", help="find the physics a simulation left out (writes DIR/report.json, .md, .rrd)")
    p.add_argument("--model", required=True, help="model name (pneumasim models)")
    p.add_argument("recordings", nargs="+", metavar="REC",
                   help="recordings to fit: .csv, .parquet, or ROS bags (.bag, .db3, .mcap, a ROS 2 bag folder) "
                        "with --map")
    p.add_argument("--holdout", nargs="+", metavar="REC", help="held-out recordings (default: last 30 %%)")
    p.add_argument("--map", metavar="MAP.toml",
                   help="import map with a [ros] section for ROS bag recordings, or a shipped one's name (ros_arm2)")
    p.add_argument("--out", required=True, help="output folder, replaced whole when the run has finished")
    p.add_argument("--gauge", action="store_true",
                   help="the recordings' pressures are gauge (relative to the room): add the model's room pressure")
    p.set_defaults(func=_cmd_doctor)
    p = sub.add_parser("import", help="convert a lab log or a ROS bag into a recording with a mapping file")
    p.add_argument("src", metavar="SRC", help="the lab's raw log, or a ROS bag (.bag, .db3, .mcap, ROS 2 bag folder)")
    p.add_argument("--map", required=True, metavar="MAP.toml",
                   help="mapping file, or the name of a shipped one (zillen_chamber, zillen_friction, ros_arm2)")
    p.add_argument("--out", required=True, metavar="REC.csv|REC.parquet",
                   help="recording to write: .csv (and its sidecar REC.json) or .parquet; not the source")
    p.add_argument("--meta", nargs="+", metavar="KEY=VALUE", help="extra sidecar metadata, e.g. bore_m=0.0257")
    p.set_defaults(func=_cmd_import)
    p = sub.add_parser("sweep", help="run a case function over many cases, or a scenario, on every core or on Ray",
                       description="pneumasim sweep MODULE:FUNCTION --cases CASES.json --out DIR, or "
                                   "pneumasim sweep SCENARIO [--fast] [--out DIR]; a rerun with the same "
                                   "--out resumes (docs/sweep.md)")
    p.add_argument("target", metavar="MODULE:FUNCTION|SCENARIO",
                   help="a case function fn(case: dict) -> dict, or a scenario name (pneumasim run --list)")
    p.add_argument("--cases", metavar="CASES.json", help="a JSON list of case objects (or JSON lines)")
    p.add_argument("--out", help="output folder: cases/<i>.json, sweep.json, results.json")
    p.add_argument("--workers", type=int, help="parallel cases (default: every CPU)")
    p.add_argument("--ray", metavar="auto|ADDRESS|local",
                   help="run on Ray: 'auto' (the cluster `ray start` made), HOST:PORT, or 'local' (start it here)")
    p.add_argument("--backend", choices=["inline", "process", "ray"], help="default: process (ray with --ray)")
    p.add_argument("--retries", type=int, default=1, help="extra attempts for a failed case (default 1)")
    p.add_argument("--fast", action="store_true", help="scenario: the shortened version")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_sweep)
    p = sub.add_parser("models", help="list the models")
    p.set_defaults(func=_cmd_models)
    return parser


def main(argv=None):
    from pneumatics.stopping import stops_cleanly

    parser = build_parser()
    args = parser.parse_args(argv)
    warnings.simplefilter("default")
    with stops_cleanly("pneumasim: "):  # Ctrl-C or SIGTERM: clean up, say so, end by the signal
        try:
            args.func(args)
        except PneumasimError as e:
            sys.exit(f"pneumasim: error: {e}")


if __name__ == "__main__":
    main()
