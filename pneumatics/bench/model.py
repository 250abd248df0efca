"""Bench models (``kind = "bench"``): their parameters and, for the cylinder, a MuJoCo replay.

* ``bench_chamber`` — one closed rigid chamber with a pressure sensor (:class:`BenchChamberCfg`);
  its physics (leak, gas-wall heat transfer) is in ``pneumatics/effects``.
* ``bench_cylinder`` — a cylinder whose rod an external drive moves along a recorded
  displacement (an input, not a state), cap chamber at a regulated pressure, load cell on the
  rod (:class:`BenchCylinderCfg`).  :func:`replay_cylinder` drives the MJCF slide joint along
  the recording and reads the MuJoCo load-cell sensor.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, replace

import numpy as np

import models
from pneumatics.config import from_table, spec
from pneumatics.errors import ConfigError
from pneumatics.recording import Recording


@dataclass(frozen=True)
class BenchChamberCfg:
    name: str = spec("chamber", "chamber name: recording column p_a.<name>")
    volume_m3: float = spec(1e-4, "chamber volume V (only conductances and heat-transfer "
                            "coefficients depend on it; time constants do not)", "m^3", 1e-8, 1.0)
    wall_area_m2: float = spec(1e-2, "wetted wall area A_w", "m^2", 1e-6, 10.0)
    heat_transfer_w_m2k: float = spec(10.0, "nominal gas-wall heat-transfer coefficient h", "W/(m^2 K)", 0.0, 1e4)
    room_pa: float = spec(101325.0, "room pressure", "Pa", 5e4, 1.2e5)
    wall_temperature_k: float = spec(293.15, "wall and room temperature T_w", "K", 200.0, 400.0)
    gas_constant_j_per_kg_k: float = spec(287.0, "specific gas constant R", "J/(kg K)", 100.0, 5000.0)
    heat_capacity_ratio: float = spec(1.4, "k = c_p/c_v", "-", 1.0, 1.7)
    pressure_resolution_pa: float = spec(100.0, "sensor resolution (smallest step in the log)", "Pa", 0.0, 1e5)


@dataclass(frozen=True)
class BenchCylinderCfg:
    name: str = spec("rod", "joint and actuator name: q.<name>, p_a.<name>, force.<name>")
    bore_m: float = spec(0.025, "piston bore (a recording's sidecar bore_m overrides it)", "m", 0.002, 0.5)
    stroke_m: float = spec(0.04, "stroke", "m", 0.001, 2.0)
    room_pa: float = spec(101325.0, "room pressure", "Pa", 5e4, 1.2e5)
    force_sign: float = spec(1.0, "load cell reads force_sign * p_g * A at rest", "-", -1.0, 1.0)
    force_resolution_n: float = spec(0.02, "load-cell resolution", "N", 0.0, 100.0)

    @property
    def area_m2(self) -> float:
        """Bore area pi d^2 / 4 [m^2]."""
        return math.pi * self.bore_m ** 2 / 4.0


def load_bench(name: str):
    """The :class:`BenchChamberCfg` or :class:`BenchCylinderCfg` of bench model ``name``."""
    path = models.fluid_path(name)
    doc = tomllib.loads(path.read_text())
    if doc.get("kind") != "bench":
        raise ConfigError(f"{path}: model {name!r} is of kind {doc.get('kind', models.VALVE_ARM)!r}, not 'bench'")
    if "chamber" in doc:
        table = dict(doc["chamber"])
        gas = doc.get("gas", {})
        for k in ("gas_constant_j_per_kg_k", "heat_capacity_ratio"):
            if k in gas:
                table[k] = gas[k]
        if "pressure_resolution_pa" in doc.get("sensor", {}):
            table["pressure_resolution_pa"] = doc["sensor"]["pressure_resolution_pa"]
        return from_table(BenchChamberCfg, table, f"{path} [chamber]")
    if "cylinder" in doc:
        table = dict(doc["cylinder"])
        if "force_resolution_n" in doc.get("sensor", {}):
            table["force_resolution_n"] = doc["sensor"]["force_resolution_n"]
        return from_table(BenchCylinderCfg, table, f"{path} [cylinder]")
    raise ConfigError(f"{path}: a bench model needs a [chamber] or a [cylinder] table")


def for_recording(cfg, rec: Recording):
    """``cfg`` with the recording's sidecar overrides (``bore_m``, ``volume_m3``, ``room_pa``)."""
    over = {k: float(rec.meta[k]) for k in ("bore_m", "volume_m3", "room_pa")
            if k in rec.meta and hasattr(cfg, k)}
    return replace(cfg, **over) if over else cfg


def replay_cylinder(cfg: BenchCylinderCfg, time_s: np.ndarray, q_m: np.ndarray, pressure_pa: np.ndarray,
                    friction_n=None, offset_n: float = 0.0) -> np.ndarray:
    """Drive the MJCF rod along ``q_m`` (N,) and return the load-cell readings (N,) [N].

    The cylinder pushes the rod with p_g A plus ``friction_n`` (N,) (positive when q grows);
    the MuJoCo force sensor between rod and drive reads it (plus the rod's inertia, tiny at
    10 mm/s), ``offset_n`` is added as a load-cell offset.  Compression reads positive.
    """
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(models.mjcf_path("bench_cylinder")))
    data = mujoco.MjData(model)
    act_drive, rod_body = model.actuator("drive").id, model.body(cfg.name).id
    sensor = model.sensor("load_cell")
    dt = model.opt.timestep
    fr = np.zeros_like(q_m) if friction_n is None else np.asarray(friction_n, float)
    data.qpos[0] = q_m[0]
    data.ctrl[act_drive] = q_m[0]
    data.xfrc_applied[rod_body, 0] = (pressure_pa[0] - cfg.room_pa) * cfg.area_m2 + fr[0]
    out = np.empty(time_s.size)
    t_sim = time_s[0]
    for i, t in enumerate(time_s):
        while t_sim < t - 1e-12:
            qi = np.interp(t_sim, time_s, q_m)
            data.ctrl[act_drive] = qi
            push = (np.interp(t_sim, time_s, pressure_pa) - cfg.room_pa) * cfg.area_m2 + np.interp(t_sim, time_s, fr)
            data.xfrc_applied[rod_body, 0] = push  # out of the barrel (+x); the drive holds the rod
            mujoco.mj_step(model, data)
            t_sim += dt
        mujoco.mj_forward(model, data)
        out[i] = -data.sensordata[sensor.adr[0]] * cfg.force_sign + offset_n
    return out
