"""The mismatch finder, ``pneumasim doctor``: one entry for every kind of model.

Each plant kind has its own doctor in a folder of its own, all writing the report contract of
DESIGN.md ("The mismatch finder"):

=============  ====================================================================
``valve_arm``  arm2, humanoid38 (Kokoro valves, cylinders, MuJoCo arm): :mod:`.valve_arm`
``jetpipe``    the jet-pipe servo actuator on its stopper bench: :mod:`.jetpipe`
``bench``      lab benches (a sealed chamber, a cylinder on a load cell): :mod:`.bench`
``hydraulic``  the SARCOS hydraulic elbow (servovalve, rotary vane, shaft): :mod:`.hydraulic`
=============  ====================================================================

What they share (statistics, least squares, smoothing, report pieces) is in
:mod:`identification.base`.  Usage::

    from identification.doctor import diagnose, summary, write
    report = diagnose("arm2", recordings, holdouts, progress=print)
    write(report, "runs/doctor")
    print(summary(report))
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import models
from pneumatics.errors import UnknownNameError

#: the model kinds a doctor exists for (models/<name>/fluid.toml ``kind``)
KINDS = ("valve_arm", "jetpipe", "bench", "hydraulic")


def kind_of(model: str) -> str:
    """The doctor kind of shipped model ``model``; an error names the models a doctor reads."""
    kind = models.model_kind(model)  # raises UnknownModelError listing the models
    if kind not in KINDS:
        raise UnknownNameError("doctor model", model,
                               [m for m in models.available() if models.model_kind(m) in KINDS])
    return kind


def room_pressure_pa(model: str) -> float:
    """The room pressure [Pa] of shipped model ``model`` (what ``--gauge`` adds to pressures);
    for a hydraulic model its tank pressure (``[power] tank_pa``, atmospheric: 1e5 Pa for the
    SARCOS elbow), the pressure a gauge transducer reads as zero."""
    kind = kind_of(model)
    if kind == "hydraulic":
        from .hydraulic.data import load_model_cfg as load_hydraulic_cfg

        return float(load_hydraulic_cfg(model).power.tank_pa)
    if kind == "valve_arm":
        from pneumatics.robot import load_robot

        return float(load_robot(model).tables.room_pa)
    if kind == "jetpipe":
        from .jetpipe.data import load_model_cfg

        return float(load_model_cfg(model).supply.room_pa)
    from pneumatics.bench.model import load_bench

    return float(load_bench(model).room_pa)


def diagnose(model: str, recordings: list, holdouts: list = (), progress: Callable[[str], None] | None = None) -> dict:
    """Diagnose ``recordings`` (``pneumatics.recording.Recording``) of shipped model ``model``
    with its kind's doctor; ``holdouts`` are judged on (default: the end of each recording).
    ``progress(message)`` is called at each stage.  Returns the report dict (report.json
    plus private ``_``-keys the writers use)."""
    kind = kind_of(model)
    if kind == "valve_arm":
        from pneumatics.robot import load_robot

        from .valve_arm.diagnose import diagnose as diagnose_arm

        robot = load_robot(model)
        report = diagnose_arm(robot, recordings, list(holdouts), progress=progress)
        report["_robot"] = robot  # for write(): report.json leaves "_" keys out
    elif kind == "jetpipe":
        from .jetpipe.diagnose import diagnose_jetpipe

        report = diagnose_jetpipe(model, recordings, list(holdouts), progress=progress)
    elif kind == "hydraulic":
        from .hydraulic.diagnose import diagnose_hydraulic

        report = diagnose_hydraulic(model, recordings, list(holdouts), progress=progress)
    else:
        from .bench.diagnose import diagnose_bench

        report = diagnose_bench(model, recordings, list(holdouts), progress=progress)
    report.setdefault("model", model)
    return report


def write(report: dict, out: str | Path) -> Path:
    """Write the report's files (report.json, report.md, plots, doctor.rrd where the kind has
    one) into folder ``out``."""
    kind = kind_of(report["model"])
    if kind == "valve_arm":
        from pneumatics.robot import load_robot

        from .valve_arm.report import write as write_arm

        robot = report.pop("_robot", None) or load_robot(report["model"])
        return write_arm(report, out, robot)
    if kind == "jetpipe":
        from .jetpipe.report import write as write_jetpipe

        return write_jetpipe(report, out)
    if kind == "hydraulic":
        from .hydraulic.report import write as write_hydraulic

        return write_hydraulic(report, out)
    from .bench.report import write as write_bench

    return write_bench(report, out)


def summary(report: dict) -> str:
    """The ten-second summary of a report, as ``pneumasim doctor`` prints it."""
    kind = kind_of(report["model"])
    if kind == "valve_arm":
        from .valve_arm.report import summary as summary_kind
    elif kind == "jetpipe":
        from .jetpipe.report import summary as summary_kind
    elif kind == "hydraulic":
        from .hydraulic.report import summary as summary_kind
    else:
        from .bench.report import summary as summary_kind
    return summary_kind(report)
