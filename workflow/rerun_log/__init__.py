"""Log a pneumasim run to Rerun (https://rerun.io): an ``.rrd`` file, a live viewer, or both.

Usage::

    logger = RerunLogger(sim.robot, "run.rrd")      # or spawn=True for a live viewer
    logger.log_static()                             # geometry (also done by the first frame)
    for _ in range(n):
        sim.step(10)
        logger.log_frame(sim)                       # 100 Hz when physics runs at 1 kHz
    logger.log_recording(table, prefix="measured")  # a whole recording, e.g. the robot's log
    logger.close()                                  # flush and finish the file (footer)

Entity paths (a contract: scenarios, the doctor and users rely on them)
-----------------------------------------------------------------------
Timeline ``sim_time``: a duration timeline, in seconds of simulated (or recorded) time.

=================================  ===========================================================
``world``                          static: view coordinates, right-handed, +Z up (MuJoCo's)
``world/<body>``                   body pose in the world frame (``data.xpos``, ``data.xquat``)
                                   as a ``Transform3D``; bodies welded to the world are logged
                                   once, as static.  ``<body>`` is the MuJoCo body name
                                   (``body<id>`` if unnamed); the world body is ``world/world``.
``world/<body>/<geom>``            static: the geom's pose in its body (``Transform3D``) and its
                                   shape (``Boxes3D``, ``Capsules3D``, ``Cylinders3D``,
                                   ``Ellipsoids3D``, ``Mesh3D``; planes as thin boxes) coloured
                                   from ``geom_rgba`` (or the material's rgba). ``<geom>`` is the
                                   geom name (``geom<id>`` if unnamed).  Geoms of groups >= 3
                                   (collision, hidden in MuJoCo's viewer) are skipped on bodies
                                   that have a visual geom; fully transparent geoms are skipped.
``joints/<joint>/q``               joint position: **deg** for hinges, m for slides
``pressure/<actuator>/<a|b>``      chamber pressure, **bar absolute** (Pa / 1e5)
``command/<actuator>/<a|b>``       valve command, V (A for current-driven valves)
``force/<actuator>``               actuator force, N (N m for rotary vanes): ``Simulation.forces``
=================================  ===========================================================

All scalars are ``Scalars``; the plot legends show entity paths, the plot titles the units.
:meth:`RerunLogger.log_recording` writes the same tree under ``<prefix>/`` (``measured/joints/
<joint>/q`` ...) plus ``joints/<joint>/qd`` (deg/s or m/s), ``joints/<joint>/ref`` (deg or m),
``joints/<joint>/tau`` (N m), ``command/<actuator>/i`` (A) and ``other/<column>`` (anything
else, as recorded).  With ``prefix=""`` it writes the very paths of :meth:`log_frame`.
A default blueprint shows the robot and four plots (joints, pressure, command, force) that
overlay the simulated and every prefixed tree.

Speed
-----
Frames are buffered (a few array copies, ~2 us per frame) and sent every ``flush_every``
frames, or after ``max_latency_s`` of wall time so a live viewer stays current, as **one**
Arrow record batch covering every entity (``rr.send_record_batch`` with ``rerun:entity_path``
column metadata; Rerun splits it into one chunk per entity).  Rerun's cost is then ~70 us per
chunk plus ~0.2-0.3 us per entity and frame (most of it the file encoder, LZ4, in a background
thread), far less than one ``rr.log`` per entity and frame (~70 us each) or one
``rr.send_columns`` per entity and flush (~200 us each, in Python).  Forces, being affine in
the pressures, are computed per batch rather than per frame.  :func:`measure_overhead` (``python
-m workflow.rerun_log [model ...]``) times logging against the bare simulation.
"""
from .arrow import TIMELINE
from .logger import PA_PER_BAR, RerunLogger
from .overhead import measure_overhead

__all__ = ["PA_PER_BAR", "TIMELINE", "RerunLogger", "measure_overhead"]
