"""Rerun logging: a headless .rrd that Rerun itself accepts, with the documented entity paths.

(``arm2`` is the session fixture of conftest.py.)"""
from __future__ import annotations

import subprocess
import sys
from collections import defaultdict

import numpy as np
import pytest

from workflow.rerun_log import RerunLogger
from workflow.rerun_log.geometry import drawn_geoms
from pneumatics.sim import Simulation

rr = pytest.importorskip("rerun")
from rerun.chunk import RrdReader  # noqa: E402


# The logger only reads the simulation's state; the numpy kernel spares the tests the
# compiled kernel's start-up (JIT) time.
KERNEL = "reference"


def rrd_verify(path):
    """``rerun rrd verify FILE`` (0.41), run as ``python -m rerun`` so the venv's CLI is used."""
    return subprocess.run([sys.executable, "-m", "rerun", "rrd", "verify", str(path)],
                          capture_output=True, text=True, timeout=60)


def read_rrd(path):
    """{entity path: (static rows, {time ns: value or row})} from the file, via Rerun's reader."""
    out = defaultdict(lambda: [0, {}])
    for chunk in RrdReader(path).stream().to_chunks():
        entry = out[chunk.entity_path]
        if chunk.is_static:
            entry[0] += chunk.num_rows
            continue
        batch = chunk.to_record_batch()
        times = batch.column("sim_time").cast("int64").to_numpy()
        if "Scalars:scalars" in batch.schema.names:
            values = [v[0] for v in batch.column("Scalars:scalars").to_pylist()]
        else:  # translation and quaternion (x, y, z, w) of a body
            values = [(p[0], q[0]) for p, q in zip(batch.column("Transform3D:translation").to_pylist(),
                                                    batch.column("Transform3D:quaternion").to_pylist())]
        entry[1].update(zip(times.tolist(), values))
    return dict(out)


def run_arm2(robot, logger, seconds=1.0):
    """100 Hz frames over ``seconds`` of a 1 kHz simulation; returns the logged states."""
    sim = Simulation(robot, kernel=KERNEL)
    sim.reset(pressure_pa=4e5)
    sim.set_command([5, 5, 10, 0])
    states = []
    for _ in range(round(seconds * 100)):
        sim.step(10)
        logger.log_frame(sim)
        states.append((sim.time, sim.data.qpos.copy(), sim.pressure.copy(), sim.command.copy(),
                       sim.forces().copy(), sim.data.xpos.copy(), sim.data.xquat.copy()))
    return sim, states


def test_one_second_of_arm2_is_a_valid_rrd(arm2, tmp_path):
    path = tmp_path / "arm2.rrd"
    logger = RerunLogger(arm2, path, recording_name="test")
    logger.log_static()
    sim, states = run_arm2(arm2, logger)
    logger.close()
    logger.close()  # idempotent

    res = rrd_verify(path)
    assert res.returncode == 0, res.stdout + res.stderr
    assert path.stat().st_size > 20_000  # geometry, 2 bodies and 12 scalar channels x 100 frames

    data = read_rrd(path)
    expected = ["/world", "/world/base", "/world/upper_link", "/world/forearm",
                "/joints/shoulder/q", "/joints/elbow/q", "/force/shoulder", "/force/elbow"]
    expected += [f"/{k}/{a}/{c}" for k in ("pressure", "command") for a in ("shoulder", "elbow") for c in "ab"]
    for entity in expected:
        assert entity in data, f"{entity} missing; have {sorted(data)}"
    # geometry: 5 visual geoms; the collision capsule (group 3) of the forearm is skipped
    geoms = [e for e in data if e.count("/") == 3 and e.startswith("/world/")]
    assert len(geoms) == 5, geoms

    # 100 frames per channel, at sim_time, in the documented units
    t_ns = [round(t * 1e9) for t, *_ in states]
    q = data["/joints/elbow/q"][1]
    assert sorted(q) == t_ns
    forearm = arm2.model.body("forearm").id
    for (t, qpos, p, u, f, xpos, xquat), tn in zip(states, t_ns):
        assert q[tn] == pytest.approx(np.degrees(qpos[1]), rel=1e-9, abs=1e-9)
        assert data["/pressure/shoulder/b"][1][tn] == pytest.approx(p[1] / 1e5, rel=1e-9)
        assert data["/command/elbow/a"][1][tn] == pytest.approx(u[2])
        assert data["/force/elbow"][1][tn] == pytest.approx(f[1], rel=1e-9, abs=1e-9)
        translation, quaternion = data["/world/forearm"][1][tn]
        assert translation == pytest.approx(xpos[forearm], abs=1e-6)
        assert quaternion == pytest.approx(xquat[forearm][[1, 2, 3, 0]], abs=1e-6)  # MuJoCo's w last
    assert data["/world/base"][0] == 1 and not data["/world/base"][1]  # welded to the world: static


def test_small_batches_extra_channels_and_recordings(arm2, tmp_path):
    path = tmp_path / "batches.rrd"
    with RerunLogger(arm2, path, flush_every=7) as logger:  # 100 frames in 15 batches
        sim = Simulation(arm2, kernel=KERNEL)
        sim.reset(pressure_pa=3e5)
        sim.set_command([10, 0, 0, 10])
        for k in range(100):
            sim.step(10)
            logger.log_frame(sim, commands=[9, 1, 1, 9], extra={"joints/elbow/ref": float(k)})
        t = 5.0 + np.arange(50) * 0.02  # after the simulated second
        logger.log_recording({"time": t, "q.elbow": np.full(50, 0.5), "p_a.shoulder": np.full(50, 2.5e5),
                              "u_b.elbow": np.full(50, 3.0), "temperature": np.ones(50)}, prefix="measured")
        logger.log_recording({"time": t, "q.shoulder": np.zeros(50), "q.elbow": np.zeros(50)},
                             prefix="", bodies=True)
    res = rrd_verify(path)
    assert res.returncode == 0, res.stdout + res.stderr
    data = read_rrd(path)
    assert len(data["/joints/shoulder/q"][1]) == 100 + 50
    assert len(data["/world/forearm"][1]) == 100 + 50
    assert sorted(data["/joints/elbow/ref"][1].values()) == list(range(100))
    assert set(data["/command/shoulder/a"][1].values()) == {9.0}
    assert np.allclose(list(data["/measured/joints/elbow/q"][1].values()), np.degrees(0.5))
    assert set(data["/measured/pressure/shoulder/a"][1].values()) == {2.5}
    assert set(data["/measured/command/elbow/b"][1].values()) == {3.0}
    assert len(data["/measured/other/temperature"][1]) == 50


def test_loggers_coexist_in_one_process(arm2, tmp_path):
    a = RerunLogger(arm2, tmp_path / "a.rrd", application_id="one")
    b = RerunLogger(arm2, tmp_path / "b.rrd", application_id="two")
    run_arm2(arm2, a, seconds=0.2)
    run_arm2(arm2, b, seconds=0.3)
    a.close()
    b.close()
    for name, frames in (("a", 20), ("b", 30)):
        assert rrd_verify(tmp_path / f"{name}.rrd").returncode == 0
        assert len(read_rrd(tmp_path / f"{name}.rrd")["/joints/elbow/q"][1]) == frames
    with pytest.raises(RuntimeError):
        a.log_frame(Simulation(arm2, kernel=KERNEL))


def test_recording_without_time_is_rejected(arm2):
    logger = RerunLogger(arm2)  # no sink: in-memory
    with pytest.raises(ValueError, match="time"):
        logger.log_recording({"q.elbow": np.zeros(3)})
    logger.close()


def test_geometry_of_every_geom_type(tmp_path):
    """Planes, spheres, ellipsoids, meshes, capsules; collision and invisible geoms skipped."""
    import types

    import mujoco

    xml = """<mujoco><asset><mesh name="tet" vertex="0 0 0 1 0 0 0 1 0 0 0 1"/>
      <material name="red" rgba="1 0 0 1"/></asset>
      <worldbody><geom name="floor" type="plane" size="0 0 1"/>
        <body name="a" pos="0 0 1"><freejoint/><geom type="sphere" size=".1" material="red"/>
          <geom type="ellipsoid" size=".1 .2 .3"/><geom type="mesh" mesh="tet"/>
          <geom type="box" size=".1 .1 .1" group="3"/>
          <body><joint name="s" type="slide"/><geom type="capsule" size=".05 .2" rgba="0 1 0 .5"/>
            <geom type="cylinder" size=".05 .2" rgba="0 0 1 0"/></body></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    robot = types.SimpleNamespace(model=model, joint_names=["s"], actuator_names=[], chamber_names=[],
                                  qpos_index=np.array([7]))
    data = mujoco.MjData(model)
    sim = types.SimpleNamespace(data=data, pressure=np.zeros(0), command=np.zeros(0), forces=lambda: np.zeros(0))
    path = tmp_path / "geoms.rrd"
    with RerunLogger(robot, path) as logger:
        kinds = {p: type(shape).__name__ for _, p, shape in drawn_geoms(logger.model, logger.body_paths)}
        for _ in range(20):
            mujoco.mj_step(model, data)
            logger.log_frame(sim)
    assert kinds == {"world/world/floor": "Boxes3D", "world/a/geom1": "Ellipsoids3D",
                     "world/a/geom2": "Ellipsoids3D", "world/a/geom3": "Mesh3D", "world/body2/geom5": "Capsules3D"}
    assert rrd_verify(path).returncode == 0
    data_ = read_rrd(path)
    assert len(data_["/world/a"][1]) == 20 and len(data_["/world/body2"][1]) == 20
    assert len(data_["/joints/s/q"][1]) == 20


def test_forces_of_an_overridden_method_are_logged_every_frame(arm2, tmp_path):
    class Braked(Simulation):  # forces that depend on more than the pressures
        def forces(self):
            return super().forces() - 100.0 * self.data.qvel

    sim = Braked(arm2, kernel=KERNEL)
    sim.reset(pressure_pa=4e5)
    sim.set_command([10, 0, 0, 10])
    path = tmp_path / "braked.rrd"
    expected = {}
    with RerunLogger(arm2, path, flush_every=16) as logger:
        for _ in range(40):
            sim.step(10)
            logger.log_frame(sim)
            expected[round(sim.time * 1e9)] = sim.forces()[1]
    logged = read_rrd(path)["/force/elbow"][1]
    assert logged.keys() == expected.keys()
    assert np.allclose([logged[t] for t in expected], list(expected.values()), rtol=1e-9)
