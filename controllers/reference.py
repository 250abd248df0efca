"""Joint-space reference trajectories made the way a person moving the robot by hand would
(paper 002 §V, Fig. 5A): reaches that stop abruptly, holds, circles and figure eights, slow
and fast parts; scaled to each joint's range minus a safety margin.

Velocities and accelerations come from a smoothing spline (SciPy ``make_smoothing_spline``)
of the sampled positions, as one would differentiate a recorded trajectory.

Standard references (issue 3): three 60 s references per robot, stored as recordings with
``ref.<joint>`` columns in ``models/<robot>/references/hand_<k>.csv`` (written by
``python -m controllers.reference``), played at the recorded ("normal") speed or twice as fast
("fast", 30 s), as paper 002 §V did with its three recorded trajectories.  A user's own
recording with ``ref.<joint>`` columns loads with :meth:`JointReference.from_recording`.
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import PchipInterpolator, make_smoothing_spline

import models
from pneumatics.errors import PneumasimError, RecordingError, UnknownNameError
from pneumatics.recording import Recording, read_csv

#: play speeds of the standard references (paper 002 §V: recorded speed and 2x "fast")
SPEEDS = {"normal": 1.0, "fast": 2.0}
#: seeds of the three standard references; the robot's name is mixed in (see :func:`standard_seed`)
STANDARD_SEEDS = (1, 2, 3)
STANDARD_DURATION_S = 60.0
#: stored sample rate [Hz]; hand motion has no content near 25 Hz, and PCHIP resampling onto the
#: control grid neither overshoots the range nor adds ripple (see :meth:`JointReference.resampled`)
STORED_RATE_HZ = 50.0
#: safety margin inside each joint's range [rad]
STANDARD_MARGIN_RAD = float(np.radians(5.0))


def min_jerk(s):
    """Minimum-jerk profile 10 s^3 - 15 s^4 + 6 s^5 of a normalised time s in [0, 1]
    (Flash & Hogan 1985): 0 -> 1 with zero velocity and acceleration at both ends."""
    return 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5


@dataclass
class JointReference:
    """A sampled reference: ``time`` (N,) s, ``q`` (N, n_joint) rad, with its spline."""

    time: np.ndarray
    q: np.ndarray
    joint_names: list
    #: smoothing-spline lambda (default 1e-7 x duration); kept consistent by time_scaled/resampled
    lam: float | None = None

    def __post_init__(self):
        self.time = np.asarray(self.time, float)
        self.q = np.asarray(self.q, float).reshape(self.time.size, -1)
        if self.q.shape[1] != len(self.joint_names):
            raise PneumasimError(f"reference: q has {self.q.shape[1]} columns for {len(self.joint_names)} joints")
        if self.lam is None:
            self.lam = 1e-7 * (self.time[-1] - self.time[0])
        self._spline = None  # built on first use (one vectorised spline for all joints)

    @property
    def duration_s(self) -> float:
        return float(self.time[-1] - self.time[0])

    def _smoothing_spline(self):
        if self._spline is None:
            self._spline = make_smoothing_spline(self.time, self.q, lam=self.lam)
        return self._spline

    def reference(self, t: float) -> np.ndarray:
        """(n_joint,) position at t (held at the ends): linear between samples, every joint at
        once, with numpy.interp's arithmetic (slope times offset plus the left sample), so the
        result is that of ``np.interp`` per joint, bit for bit."""
        time = self.time
        if t <= time[0]:
            return self.q[0].copy()
        if t >= time[-1]:
            return self.q[-1].copy()
        i = int(np.searchsorted(time, t, side="right")) - 1
        slope = (self.q[i + 1] - self.q[i]) / (time[i + 1] - time[i])
        return slope * (t - time[i]) + self.q[i]

    def derivatives(self, t: np.ndarray):
        """(q, qd, qdd) each (len(t), n_joint) from the smoothing splines."""
        s = self._smoothing_spline()
        t = np.asarray(t, float)
        return tuple(np.asarray(s.derivative(k)(t) if k else s(t)).reshape(t.size, -1) for k in range(3))

    def to_recording(self, meta: dict | None = None) -> Recording:
        return Recording(self.time.copy(), {f"ref.{j}": self.q[:, i] for i, j in enumerate(self.joint_names)},
                         {"kind": "reference", **(meta or {})})

    # -- loading and re-timing ------------------------------------------------------------
    @classmethod
    def from_recording(cls, rec, joint_names=None) -> JointReference:
        """The reference in a recording's ``ref.<joint>`` columns (DESIGN.md "Recordings").

        Args:
          rec: a :class:`~pneumatics.recording.Recording` or a path to a CSV recording.
          joint_names: the joints the reference must cover (e.g. ``robot.joint_names``), in the
            order wanted; default: every ``ref.<joint>`` column, in file order.
        Returns:
          the reference with its time shifted to start at 0.
        Raises:
          RecordingError naming the missing ``ref.<joint>`` columns, or if the recording has
          none, fewer than 5 rows, or non-finite values.
        """
        if not isinstance(rec, Recording):
            rec = read_csv(rec)
        have = rec.names("ref")
        if not have:
            raise RecordingError(f"{rec.source}: no reference columns; a reference recording needs one "
                                 f"'ref.<joint>' column per joint (columns: {', '.join(list(rec.columns)[:8])})")
        joints = list(have) if joint_names is None else list(joint_names)
        missing = [j for j in joints if j not in have]
        if missing:
            raise RecordingError(f"{rec.source}: missing reference column(s) "
                                 f"{', '.join('ref.' + j for j in missing)} for joint(s) {', '.join(missing)}; "
                                 f"the recording has ref columns for: {', '.join(have)}")
        if len(rec) < 5:
            raise RecordingError(f"{rec.source}: a reference needs at least 5 rows, has {len(rec)}")
        q = rec.matrix("ref", joints)
        if not np.all(np.isfinite(q)) or np.any(np.diff(rec.time) <= 0):
            raise RecordingError(f"{rec.source}: reference columns must be finite with strictly increasing time")
        return cls(rec.time - rec.time[0], q, joints)

    def time_scaled(self, speed: float) -> JointReference:
        """The same motion played ``speed`` times faster (time divided by ``speed``); the spline's
        lambda scales by 1/speed^3 (the roughness integral of f'' grows by speed^3), so the
        derivatives are exactly speed and speed^2 times the original ones."""
        if not speed > 0:
            raise PneumasimError(f"reference speed must be > 0, got {speed!r}")
        return JointReference(self.time / speed, self.q.copy(), list(self.joint_names), self.lam / speed ** 3)

    def resampled(self, rate_hz: float) -> JointReference:
        """Resampled onto a ``rate_hz`` grid by piecewise-cubic Hermite (PCHIP) interpolation,
        which never leaves the range of the samples (no overshoot past the safety margin)."""
        n = int(np.floor(self.duration_s * rate_hz + 1e-9)) + 1
        grid = self.time[0] + np.arange(n) / rate_hz
        q = PchipInterpolator(self.time, self.q, axis=0)(grid)
        # the spline's data term sums over samples: keep the smoothing the same per unit time
        return JointReference(grid, q, list(self.joint_names), self.lam * n / self.time.size)


def hand_moved(joint_names, joint_range, duration_s: float, seed: int, *, speed: float = 1.0,
               margin_rad: float = np.radians(5.0), rate_hz: float = 100.0, start_hold_s: float = 1.0,
               extreme_probability: float = 0.2) -> JointReference:
    """A procedural "moved by hand" reference from ``seed``; ``speed`` 2 = the fast version."""
    rng = np.random.default_rng(seed)
    lo = np.asarray(joint_range)[:, 0] + margin_rad
    hi = np.asarray(joint_range)[:, 1] - margin_rad
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    n = len(joint_names)
    dt = 1.0 / rate_hz
    t_total = duration_s * speed  # built on the slow clock, then time-compressed by `speed`
    pieces = [np.zeros((int(start_hold_s * speed * rate_hz), n))]  # normalised [-1, 1] positions
    cur = np.zeros(n)
    length = len(pieces[0])
    while length * dt < t_total:
        kind = rng.choice(["reach", "hold", "circle", "eight"], p=[0.45, 0.2, 0.2, 0.15])
        if kind == "reach":
            extreme = rng.random() < extreme_probability
            target = rng.uniform(-1, 1, n) if not extreme else np.sign(rng.uniform(-1, 1, n)) * rng.uniform(0.85, 1.0, n)
            steps = max(2, int(rng.uniform(0.4, 0.9) * rate_hz))
            s = min_jerk(np.linspace(0, 1, steps))[:, None]
            seg = cur + (target - cur) * s
        elif kind == "hold":
            seg = np.repeat(cur[None], int(rng.uniform(0.4, 1.5) * rate_hz), axis=0)
        else:
            f = rng.uniform(0.15, 0.9)
            cycles = rng.integers(1, 4)
            steps = int(cycles / f * rate_hz)
            tt = np.arange(steps) * dt
            amp = rng.uniform(0.25, 0.6, n)
            ratio = np.where(np.arange(n) % 2 == 0, 1.0, 2.0 if kind == "eight" else 1.0)
            phase = rng.uniform(0, 2 * np.pi, n)
            wave = amp * (np.sin(2 * np.pi * f * ratio * tt[:, None] + phase) - np.sin(phase))
            centre = np.clip(cur, -1 + amp, 1 - amp)
            ramp = min_jerk(np.clip(tt / 0.3, 0, 1))[:, None]
            seg = cur + (centre - cur) * ramp + wave * ramp
            seg = np.clip(seg, -1, 1)
        pieces.append(seg)
        cur = seg[-1]
        length += len(seg)
    norm = np.concatenate(pieces)[: round(t_total * rate_hz) + 1]
    t_slow = np.arange(len(norm)) * dt
    time = t_slow / speed
    # resample onto the control grid of the compressed clock
    grid = np.arange(round(duration_s * rate_hz) + 1) * dt
    norm = np.column_stack([np.interp(grid, time, norm[:, j]) for j in range(n)])
    return JointReference(grid, mid + half * norm, list(joint_names))


# -- standard references -------------------------------------------------------------------

def standard_seed(robot_name: str, k: int) -> int:
    """Seed of standard reference ``k`` (1-3) of ``robot_name``: different robots get different motions."""
    return 1000 * sum(robot_name.encode()) + STANDARD_SEEDS[k - 1]


def reference_path(robot_name: str, k: int) -> Path:
    """``models/<robot>/references/hand_<k>.csv``."""
    return models.folder(robot_name) / "references" / f"hand_{k}.csv"


def make_standard_reference(robot, k: int) -> JointReference:
    """Standard reference ``k`` (1-3) of a loaded robot (:func:`pneumatics.robot.load_robot`),
    at normal speed, sampled at :data:`STORED_RATE_HZ`."""
    return hand_moved(robot.joint_names, robot.joint_range(), STANDARD_DURATION_S, standard_seed(robot.name, k),
                      margin_rad=STANDARD_MARGIN_RAD, rate_hz=STORED_RATE_HZ)


def write_standard_references(robot_name: str) -> list[Path]:
    """(Re)generate the three stored references of ``robot_name``; returns the CSV paths."""
    # only the generator needs the compiled model
    from pneumatics.robot import load_robot

    robot = load_robot(robot_name)
    paths = []
    for k in range(1, len(STANDARD_SEEDS) + 1):
        ref = make_standard_reference(robot, k)
        meta = {"model": robot_name, "seed": standard_seed(robot_name, k), "speed": 1.0,
                "margin_rad": STANDARD_MARGIN_RAD, "rate_hz": STORED_RATE_HZ,
                "generator": "controllers.reference.hand_moved",
                "regenerate": "python -m controllers.reference --robot " + robot_name}
        path = reference_path(robot_name, k)
        path.parent.mkdir(parents=True, exist_ok=True)
        ref.to_recording(meta).to_csv(path, digits=6)
        paths.append(path)
    return paths


def standard_references(robot_name: str, speed: str | float = "normal", rate_hz: float = 100.0) -> list[JointReference]:
    """The three standard references of ``robot_name`` (stored recordings), played at ``speed``.

    Args:
      speed: ``"normal"`` (60 s, as recorded), ``"fast"`` (the same motion 2x faster, 30 s),
        or a number (play-speed factor).
      rate_hz: sample rate of the returned references (the control rate).
    Returns:
      three :class:`JointReference`, each resampled onto a ``rate_hz`` grid starting at 0.
    """
    if isinstance(speed, str):
        if speed not in SPEEDS:
            raise UnknownNameError("reference speed", speed, SPEEDS)
        factor = SPEEDS[speed]
    else:
        factor = float(speed)
    out = []
    for k in range(1, len(STANDARD_SEEDS) + 1):
        path = reference_path(robot_name, k)
        if not path.is_file():
            raise PneumasimError(f"{path}: standard reference not found; generate it with "
                                 f"`python -m controllers.reference --robot {robot_name}`")
        out.append(JointReference.from_recording(read_csv(path)).time_scaled(factor).resampled(rate_hz))
    return out


def main(argv=None):
    """``python -m controllers.reference [--robot NAME ...]``: write the stored standard references."""
    parser = argparse.ArgumentParser(prog="python -m controllers.reference", description=main.__doc__)
    parser.add_argument("--robot", action="append", help="model name (repeatable; default arm2 and humanoid38)")
    args = parser.parse_args(argv)
    for name in args.robot or ["arm2", "humanoid38"]:
        for path in write_standard_references(name):
            print(f"wrote {path}")


if __name__ == "__main__":
    main()
