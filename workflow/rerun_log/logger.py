"""The logger itself: layout of the entity tree, static geometry, buffered frames, whole
recordings, the default blueprint (the contract is in the package docstring)."""
from __future__ import annotations

import math
import shutil
import sys
import time as _time
import uuid
import warnings
from collections.abc import Mapping
from pathlib import Path

import mujoco
import numpy as np
import pyarrow as pa
import rerun as rr
import rerun.blueprint as rrb

from pneumatics.robot import Robot

from .arrow import (
    TIME_FIELD,
    entity_part,
    ns,
    scalar_field,
    transform_fields,
    vec_array,
    xyzw,
)
from .forces import affine_forces
from .geometry import drawn_geoms

PA_PER_BAR = 1e5
_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
_PLOTS = ("joints", "pressure", "command", "force")


class RerunLogger:
    """Logs body poses (with geometry), joint angles, pressures, valve commands, forces.

    Args:
      robot: the :class:`~pneumatics.robot.Robot` being simulated (names and geometry).
      path: ``.rrd`` file to write (works headless); ``None`` for none.
      spawn: start a Rerun viewer and stream to it (as well as to ``path`` if given).
      application_id, recording_name: shown in the viewer.
      flush_every: frames buffered before they are sent in one batch.
      max_latency_s: also send when the oldest buffered frame is this old (wall time), so a
        live viewer keeps up; default 0.1 s with ``spawn``, else none (``math.inf``: sending
        by count only costs least).  Every send costs ~70 us per entity (chunk) in all, so
        the interval stretches to 20 times the last send's duration if that is longer.

    With neither ``path`` nor ``spawn`` the data stays in Rerun's in-memory buffer
    (``logger.recording`` is the ``rr.RecordingStream``: attach a sink yourself).
    Each logger has its own recording stream, so several can coexist in one process.
    """

    def __init__(self, robot: Robot, path: str | Path | None = None, spawn: bool = False,
                 application_id: str = "pneumasim", recording_name: str | None = None, *,
                 flush_every: int = 2000, max_latency_s: float | None = None, port: int = 9876):
        self.robot = robot
        self.model = robot.model
        self.path = Path(path) if path is not None else None
        self.flush_every = max(1, int(flush_every))
        if max_latency_s is None:
            max_latency_s = 0.1 if spawn else math.inf
        self.max_latency_s = None if max_latency_s == math.inf else float(max_latency_s)
        self._latency = self.max_latency_s  # stretched by flush() when sending is slow
        self._flush_due = math.inf
        self.recording = rr.RecordingStream(application_id, recording_id=uuid.uuid4())
        self._closed = False
        self._static_done = False
        self._prefixes: list[str] = []
        sinks = []
        if spawn:
            exe = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
            rr.spawn(port=port, connect=False, executable_path=exe if Path(exe).exists() else None,
                     recording=self.recording)
            sinks.append(rr.GrpcSink(f"rerun+http://127.0.0.1:{port}/proxy"))
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            sinks.append(rr.FileSink(str(self.path)))
        if sinks:
            self.recording.set_sinks(*sinks)
        if recording_name:
            self.recording.send_recording_name(recording_name)
        self._setup_layout()

    # -- layout ---------------------------------------------------------------------------
    def _setup_layout(self):
        m, robot = self.model, self.robot
        self.body_paths = [f"world/{entity_part(m.body(b).name or f'body{b}')}" for b in range(m.nbody)]
        weld = np.asarray(m.body_weldid)
        self._moving = np.array([b for b in range(1, m.nbody) if weld[b] != 0], int)
        self._fixed = np.array([b for b in range(1, m.nbody) if weld[b] == 0], int)
        jt = [int(m.jnt_type[m.joint(j).id]) for j in robot.joint_names]
        # by name: a simulation may add joints of its own (backlash drives)
        self._qadr = np.array([m.jnt_qposadr[m.joint(j).id] for j in robot.joint_names], int)
        self._qscale = np.array([180.0 / math.pi if t == _HINGE else 1.0 for t in jt])
        acts = robot.actuator_names
        chambers = robot.chamber_names
        self._channels: list[str] = (  # entity paths of the scalars, in the order of flush()
            [f"joints/{entity_part(j)}/q" for j in robot.joint_names]
            + [f"pressure/{entity_part(a)}/{c}" for a, c in chambers]
            + [f"command/{entity_part(a)}/{c}" for a, c in chambers]
            + [f"force/{entity_part(a)}" for a in acts])
        nch, na = len(chambers), len(acts)
        fields = [TIME_FIELD]
        for b in self._moving:
            fields += transform_fields("/" + self.body_paths[b])
        fields += [scalar_field("/" + p) for p in self._channels]
        self._schema = pa.schema(fields)
        # frame buffer: whole MuJoCo arrays are copied per frame (cheapest), selected at flush
        cap, m = self.flush_every, self.model
        self._t = np.empty(cap)
        self._xpos = np.empty((cap, m.nbody, 3))
        self._xquat = np.empty((cap, m.nbody, 4))
        self._qpos = np.empty((cap, m.nq))
        self._p = np.empty((cap, nch))
        self._u = np.empty((cap, nch))
        self._f = np.empty((cap, na))
        self._affine = None  # (M, c) with forces = p @ M.T + c, found at the first frame
        self._first = True
        self._sim = None  # the simulation of the current batch (to re-check the affine law)
        self._data = self._views = None
        self._n = 0
        self._extra_keys: list[str] = []
        self._extra = np.empty((cap, 0))

    # -- static ---------------------------------------------------------------------------
    def log_static(self):
        """Geometry of every geom, poses of bodies welded to the world, the default layout.
        Called by the first :meth:`log_frame` if not called before; later calls do nothing."""
        if self._static_done:
            return
        self._static_done = True
        rec, m = self.recording, self.model
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        d = mujoco.MjData(m)
        mujoco.mj_kinematics(m, d)
        for b in self._fixed:
            rec.log(self.body_paths[b], rr.Transform3D(translation=d.xpos[b], quaternion=xyzw(d.xquat[b])),
                    static=True)
        for g, path, shape in drawn_geoms(self.model, self.body_paths):
            rec.log(path, rr.Transform3D(translation=m.geom_pos[g], quaternion=xyzw(m.geom_quat[g])), shape,
                    static=True)
        self._send_blueprint()

    def _send_blueprint(self):
        trees = [""] + [f"{p}/" for p in self._prefixes]
        units = {"joints": "joints [deg | m]", "pressure": "pressure [bar abs]",
                 "command": "valve command [V]", "force": "force [N]"}
        plots = [rrb.TimeSeriesView(name=units[k], origin="/", contents=[f"+ /{t}{k}/**" for t in trees])
                 for k in _PLOTS]
        bp = rrb.Blueprint(rrb.Horizontal(rrb.Spatial3DView(name="robot", origin="/world"),
                                          rrb.Vertical(*plots), column_shares=[3, 2]),
                           collapse_panels=False)
        self.recording.send_blueprint(bp, make_active=False, make_default=True)

    # -- frames ---------------------------------------------------------------------------
    def log_frame(self, sim, commands=None, extra: Mapping[str, float] | None = None):
        """Buffer one frame at ``sim.time``: poses of moving bodies and all scalar channels.

        ``commands`` (n_ch,) [V] replaces ``sim.command`` (e.g. the controller's unclipped
        output); ``extra`` maps further entity paths to scalars for this frame (e.g.
        ``{"joints/elbow/ref": 30.0}``, in the unit you choose; missing frames are NaN).
        """
        i = self._n
        if i == 0:  # buffer empty: start of a batch (cheap checks live here)
            if self._closed:
                raise RuntimeError("RerunLogger is closed")
            m = getattr(sim, "model", self.model)
            if self._first and (m.nq, m.nbody) != (self.model.nq, self.model.nbody):
                self.model = m  # the simulation built a model of its own (effect backlash)
                self._setup_layout()
            if not self._static_done:
                self.log_static()
            if self._first:
                self._first = False
                self._affine = affine_forces(sim)
            self._sim = sim
            if self._latency is not None:
                self._flush_due = _time.perf_counter() + self._latency
        elif self._latency is not None and not i & 15 and _time.perf_counter() > self._flush_due:
            self.flush()
            i = 0
            self._flush_due = _time.perf_counter() + self._latency
        d = sim.data
        if d is not self._data:  # numpy views into MjData, cached (each access costs ~0.25 us)
            self._data, self._views = d, (d.xpos, d.xquat, d.qpos)
        xpos, xquat, qpos = self._views
        self._t[i] = d.time
        self._xpos[i] = xpos
        self._xquat[i] = xquat
        self._qpos[i] = qpos
        self._p[i] = sim.pressure
        self._u[i] = sim.command if commands is None else commands
        if self._affine is None:
            self._f[i] = sim.forces()
        if extra or self._extra_keys:
            self._put_extra(i, extra or {})
        self._n = i + 1
        if self._n >= self.flush_every:
            self.flush()

    def _put_extra(self, i, extra):
        extra = {k.strip("/"): v for k, v in extra.items()}
        new = [k for k in extra if k not in self._extra_keys]
        if new:
            self._extra_keys += new
            self._extra = np.hstack([self._extra, np.full((self._extra.shape[0], len(new)), np.nan)])
        row = self._extra[i]
        row[:] = np.nan
        for j, k in enumerate(self._extra_keys):
            if k in extra:
                row[j] = extra[k]

    def flush(self):
        """Send the buffered frames (one record batch for all entities)."""
        n = self._n
        if n == 0:
            return
        self._n = 0
        t0 = _time.perf_counter()
        cols = [pa.array(ns(self._t[:n]), pa.duration("ns"))]
        if self._moving.size:  # one float32 Arrow buffer each for positions and quaternions
            nb = self._moving.size
            pos = np.empty((nb, n, 3), np.float32)  # (body, frame, xyz)
            pos[...] = self._xpos[:n, self._moving].transpose(1, 0, 2)
            wxyz = self._xquat[:n, self._moving].transpose(1, 0, 2)
            quat = np.empty((nb, n, 4), np.float32)  # (body, frame, xyzw)
            quat[..., :3] = wxyz[..., 1:]
            quat[..., 3] = wxyz[..., 0]
            pos, quat = pa.array(pos.ravel()), pa.array(quat.ravel())
            for k in range(self._moving.size):  # zero-copy slices, one per body
                cols.append(pa.FixedSizeListArray.from_arrays(pos.slice(3 * n * k, 3 * n), 3))
                cols.append(pa.FixedSizeListArray.from_arrays(quat.slice(4 * n * k, 4 * n), 4))
        p = self._p[:n]
        if self._affine is not None and self._affine_holds():
            mat, c = self._affine
            f = p @ mat.T + c
        elif self._affine is not None:  # it held at the first frame only: forces of this batch unknown
            self._affine = None
            f = np.full((n, self._f.shape[1]), np.nan)
        else:
            f = self._f[:n]
        vals = np.concatenate([(self._qpos[:n, self._qadr] * self._qscale).T, p.T / PA_PER_BAR,
                               self._u[:n].T, f.T])  # (channel, frame): a new array, rows
        # contiguous; Arrow shares numpy memory, so no column may view the reused frame buffer
        cols += [pa.array(row) for row in vals]
        schema = self._schema
        if self._extra_keys:
            schema = pa.schema(list(schema) + [scalar_field("/" + k) for k in self._extra_keys])
            extra = np.array(self._extra[:n].T, order="C")  # a copy: Arrow shares numpy memory
            cols += [pa.array(row) for row in extra]
        self.recording.send_record_batch(pa.RecordBatch.from_arrays(cols, schema=schema))
        if self.max_latency_s is not None:
            self._latency = max(self.max_latency_s, 20.0 * (_time.perf_counter() - t0))

    def _affine_holds(self) -> bool:
        """Does the affine force law found at the first frame still give ``sim.forces()``?"""
        sim = self._sim
        if sim is None:
            return True
        mat, c = self._affine
        expect, got = mat @ sim.pressure + c, np.asarray(sim.forces(), float)
        if np.allclose(got, expect, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(expect).max(initial=0.0))):
            return True
        warnings.warn("Simulation.forces() is no longer affine in the pressures; forces of the "
                      "current batch are logged as NaN and from now on every frame", stacklevel=3)
        return False

    # -- whole recordings -------------------------------------------------------------------
    def log_recording(self, recording_table, prefix: str = "measured", *, bodies: bool = False):
        """Log a whole recording in one batch on the ``sim_time`` timeline.

        ``recording_table`` maps column names (DESIGN.md "Recordings": ``time``, ``q.<joint>``,
        ``p_a.<actuator>`` ...) to 1-D arrays: a dict, a :class:`~pneumatics.recording.Recording`,
        a pandas DataFrame or a numpy structured array.  Entities go under ``<prefix>/`` (see
        the module docstring; ``prefix=""`` gives the paths of :meth:`log_frame`).
        ``bodies=True`` also poses ``world/<body>`` from the recorded joint angles (every joint
        must be recorded), to replay the recorded motion on the robot's geometry.
        """
        if self._closed:
            raise RuntimeError("RerunLogger is closed")
        if not self._static_done:
            self.log_static()
        names = column_names(recording_table)
        if "time" not in names:
            raise ValueError(f"recording has no 'time' column; columns: {', '.join(names)}")
        t = np.asarray(recording_table["time"], float)
        pre = f"{prefix.strip('/')}/" if prefix and prefix.strip("/") else ""
        joint_scale = dict(zip(self.robot.joint_names, self._qscale))
        fields, cols = [TIME_FIELD], [pa.array(ns(t), pa.duration("ns"))]
        for col in names:
            if col == "time":
                continue
            x = np.asarray(recording_table[col], float)
            if x.shape != t.shape:
                raise ValueError(f"recording column {col!r} has shape {x.shape}, 'time' has {t.shape}")
            path, scale = self._recording_entity(col, joint_scale)
            fields.append(scalar_field("/" + pre + path))
            cols.append(pa.array(x * scale))
        if len(fields) > 1:
            self.recording.send_record_batch(pa.RecordBatch.from_arrays(cols, schema=pa.schema(fields)))
        if bodies:
            self._log_recorded_bodies(recording_table, t)
        key = pre.rstrip("/")
        if key and key not in self._prefixes:
            self._prefixes.append(key)
            self._send_blueprint()

    def _recording_entity(self, col: str, joint_scale) -> tuple[str, float]:
        """(entity path without prefix, scale to the logged unit) of a recording column."""
        kind, _, name = col.partition(".")
        if name:
            n = entity_part(name)
            if kind in ("q", "qd", "ref") and name in joint_scale:
                return f"joints/{n}/{kind}", joint_scale[name]
            if kind == "tau":
                return f"joints/{n}/tau", 1.0
            if kind in ("p_a", "p_b"):
                return f"pressure/{n}/{kind[-1]}", 1 / PA_PER_BAR
            if kind in ("u_a", "u_b"):
                return f"command/{n}/{kind[-1]}", 1.0
            if kind == "i":
                return f"command/{n}/i", 1.0
            if kind == "force":
                return f"force/{n}", 1.0
        return f"other/{entity_part(col)}", 1.0

    def _log_recorded_bodies(self, table, t):
        m = self.model
        have = set(column_names(table))
        missing = [j for j in self.robot.joint_names if f"q.{j}" not in have]
        if missing:
            raise ValueError(f"bodies=True needs every joint angle; missing columns: "
                             f"{', '.join('q.' + j for j in missing)}")
        q = np.stack([np.asarray(table[f"q.{j}"], float) for j in self.robot.joint_names], axis=1)
        d = mujoco.MjData(m)
        pos = np.empty((t.size, self._moving.size, 3))
        quat = np.empty((t.size, self._moving.size, 4))
        for r in range(t.size):
            d.qpos[self._qadr] = q[r]
            mujoco.mj_kinematics(m, d)
            pos[r] = d.xpos[self._moving]
            quat[r] = d.xquat[self._moving]
        fields, cols = [TIME_FIELD], [pa.array(ns(t), pa.duration("ns"))]
        quat = xyzw(quat)
        for k, b in enumerate(self._moving):
            fields += transform_fields("/" + self.body_paths[b])
            cols += [vec_array(pos[:, k], 3), vec_array(quat[:, k], 4)]
        if len(fields) > 1:
            self.recording.send_record_batch(pa.RecordBatch.from_arrays(cols, schema=pa.schema(fields)))

    # -- end --------------------------------------------------------------------------------
    def close(self):
        """Send buffered frames, flush, and finish the file (its footer); idempotent."""
        if self._closed:
            return
        if not self._static_done:
            self.log_static()
        self.flush()
        self._closed = True
        self.recording.flush()
        self.recording.disconnect()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def column_names(table) -> list[str]:
    """Column names of a dict, pandas DataFrame, numpy structured array or
    :class:`pneumatics.recording.Recording` (whose ``columns`` excludes ``time``)."""
    if hasattr(table, "keys"):
        return [str(k) for k in table.keys()]
    if getattr(getattr(table, "dtype", None), "names", None):
        return list(table.dtype.names)
    if hasattr(table, "columns") and hasattr(table, "time"):
        return ["time"] + [str(c) for c in table.columns if c != "time"]
    raise TypeError(f"cannot read columns of a {type(table).__name__}: expected a dict of arrays, a "
                    "DataFrame, a structured array or a pneumatics.recording.Recording")
