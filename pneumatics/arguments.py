"""Checks of the Python API's arguments (Simulation.step/reset/set_command and the jet-pipe and
hydraulic simulations' counterparts): a bad argument raises :class:`ArgumentError` naming the
argument, what it got and the valid range, before any state changes.

Why these bounds:
* a step count is a positive whole number: ``step(0)`` let chambers fill while time stood
  still and ``step(-5)`` subtracted from the DAQ sample count (negative means);
* a chamber pressure is absolute: below ``MIN_PRESSURE_PA`` (1 kPa, a near vacuum no pneumatic
  chamber reaches: the ideal-gas pressure ODE of paper 002 eq. 9 divides by it) it is a gauge
  value or a unit slip, and above ``MAX_PRESSURE_OVER_SUPPLY`` times the supply nothing in the
  circuit can have put it there (the supply is the highest pressure a valve connects).
"""
from __future__ import annotations

import numbers

import numpy as np

from .errors import ArgumentError, UnknownNameError

MIN_PRESSURE_PA = 1.0e3
MAX_PRESSURE_OVER_SUPPLY = 2.0


def step_count(n, where: str = "step") -> int:
    """``n`` as an int >= 1 (numpy integers accepted; bools, floats and strings are not)."""
    if type(n) is int and n >= 1:  # the common case, checked first: step() runs every control period
        return n
    if isinstance(n, bool) or not isinstance(n, numbers.Integral):
        raise ArgumentError(f"{where}(n): n must be a whole number of physics steps >= 1, got {n!r} "
                            f"({type(n).__name__})")
    if n < 1:
        raise ArgumentError(f"{where}(n): n must be >= 1 physics step, got {n}")
    return int(n)


def finite_vector(value, shape: tuple, argument: str, labels=None) -> np.ndarray:
    """``value`` as a float array of ``shape`` with every entry finite."""
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ArgumentError(f"{argument}: expected numbers, got {value!r}") from None
    if arr.shape != tuple(shape):
        raise ArgumentError(f"{argument}: expected shape {tuple(shape)}, got {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        where = ([str(labels[i]) for i in np.flatnonzero(bad.ravel())] if labels is not None
                 else [str(i) for i in np.flatnonzero(bad.ravel())])
        raise ArgumentError(f"{argument}: NaN or inf at {', '.join(where)}")
    return arr


def chamber_pressures(pressure_pa, n_chambers: int, supply_pa: float, labels=None) -> np.ndarray:
    """(n_chambers,) absolute pressures [Pa] from a scalar or a vector, each finite and within
    [MIN_PRESSURE_PA, MAX_PRESSURE_OVER_SUPPLY * supply_pa]."""
    arr = np.asarray(pressure_pa, dtype=float) if _numeric(pressure_pa) else None
    if arr is None:
        raise ArgumentError(f"reset(pressure_pa): expected a number or {n_chambers} numbers [Pa abs], "
                            f"got {pressure_pa!r}")
    if arr.ndim == 0:
        arr = np.full(n_chambers, float(arr))
    arr = finite_vector(arr, (n_chambers,), "reset(pressure_pa)", labels)
    hi = MAX_PRESSURE_OVER_SUPPLY * supply_pa
    out = (arr < MIN_PRESSURE_PA) | (arr > hi)
    if out.any():
        i = int(np.argmax(out))
        name = labels[i] if labels is not None else str(i)
        raise ArgumentError(f"reset(pressure_pa): {arr[i]:.6g} Pa for chamber {name} is outside "
                            f"{MIN_PRESSURE_PA:g}..{hi:.6g} Pa (absolute, up to {MAX_PRESSURE_OVER_SUPPLY:g} x "
                            f"the supply {supply_pa:.6g} Pa); a gauge pressure needs the room pressure added")
    return arr


def joint_positions(qpos, joint_names, joint_range, limited) -> np.ndarray:
    """(n_joint,) positions [rad or m], finite and inside each limited joint's range."""
    q = finite_vector(qpos, (len(joint_names),), "reset(qpos)", joint_names)
    lo, hi = joint_range[:, 0], joint_range[:, 1]
    tol = 1e-4 * np.maximum(1.0, hi - lo)  # a limit typed rounded to 4 digits
    out = np.asarray(limited, bool) & ((q < lo - tol) | (q > hi + tol))
    if out.any():
        i = int(np.argmax(out))
        raise ArgumentError(f"reset(qpos): joint {joint_names[i]} = {q[i]:.6g} is outside its range "
                            f"[{lo[i]:.6g}, {hi[i]:.6g}] (rad, or m for a slide joint)")
    return q


def keyframe_id(model, keyframe: str) -> int | None:
    """The MuJoCo keyframe ``keyframe``'s id; None for the default "home" of a model without
    keyframes; an unknown name raises, listing the model's keyframes."""
    names = [model.key(i).name for i in range(model.nkey)]
    if keyframe in names:
        return names.index(keyframe)
    if not names and keyframe == "home":
        return None
    if not names:
        raise ArgumentError(f"reset(keyframe): {keyframe!r}, but the model has no keyframes (use None)")
    raise UnknownNameError("keyframe", keyframe, names)


def command_in_range(value: float, lo: float, hi: float, argument: str, unit: str, why: str = "") -> float:
    """A scalar command, finite and within [lo, hi] (``why``: the bounds' reason, for the message)."""
    if isinstance(value, bool) or not _numeric(value) or np.ndim(value) != 0:
        raise ArgumentError(f"{argument}: expected one number [{unit}], got {value!r}")
    v = float(value)
    if not np.isfinite(v):
        raise ArgumentError(f"{argument}: {v} is not a finite number [{unit}]")
    if not lo <= v <= hi:
        raise ArgumentError(f"{argument}: {v:.6g} {unit} is outside {lo:.6g}..{hi:.6g} {unit}" + (f" ({why})" if why else ""))
    return v


def _numeric(value) -> bool:
    try:
        np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return False
    return True
