"""The physics loop (:func:`pneumatics.kernel.physics_steps`) and the valve command's path
(:func:`pneumatics.command_kernel.command_step`) behind plain C entry points.

``Simulation.step`` and ``Simulation.set_command`` call compiled code once per control
period from Python.  Through
numba's dispatcher that call costs 1-2 us with the loop's 17 arguments (each array's type is
worked out and unboxed anew every call), as much as half an arm2 physics step.  Here the
arguments are written once into an ``int64`` block (addresses and shapes) and the loop is
called through ctypes with two arguments (~0.3 us): :class:`StepCall`.  The arithmetic is
the kernel's own, so results do not change; where an argument is not a C-contiguous float64
array the caller keeps the dispatcher.  :class:`CommandCall` does the same for the command's
13 arguments: about 1.5 us a period through the dispatcher, 0.85 us through the C entry point
with its copy of the commands (arm2, 2026-11-26).
"""
from __future__ import annotations

import ctypes

import numba
import numpy as np
from numba import types
from numba.extending import intrinsic

from .command_kernel import command_step
from .kernel import physics_steps

#: dimensions of the arrays of physics_steps after (n, fns, model address, data address), in its
#: order: p, areas, prev_length, length, ctrl, act, ch, glob, qpos, qvel, acc, qfrc_applied, fric
NDIM = (1, 2, 1, 1, 1, 2, 2, 1, 1, 1, 1, 1, 2)
HEAD = 3  # block[0..2]: address of the MuJoCo functions' table, MjModel*, MjData*


def _pointer_intrinsic(dtype):
    @intrinsic
    def pointer(typingctx, address):
        sig = types.CPointer(dtype)(types.int64)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(types.CPointer(dtype)))

        return sig, codegen

    return pointer


_f64_pointer = _pointer_intrinsic(types.float64)
_u64_pointer = _pointer_intrinsic(types.uint64)


@numba.njit(cache=True, inline="always")
def _vector(block, j):
    i = HEAD + 3 * j
    return numba.carray(_f64_pointer(block[i]), (block[i + 1],))


@numba.njit(cache=True, inline="always")
def _matrix(block, j):
    i = HEAD + 3 * j
    return numba.carray(_f64_pointer(block[i]), (block[i + 1], block[i + 2]))


@numba.cfunc(types.void(types.int64, types.CPointer(types.int64)), cache=True, error_model="numpy")
def _physics_steps_c(n, block):
    fns = numba.carray(_u64_pointer(block[0]), (6,))
    physics_steps(n, fns, np.uint64(block[1]), np.uint64(block[2]), _vector(block, 0), _matrix(block, 1),
                  _vector(block, 2), _vector(block, 3), _vector(block, 4), _matrix(block, 5), _matrix(block, 6),
                  _vector(block, 7), _vector(block, 8), _vector(block, 9), _vector(block, 10), _vector(block, 11),
                  _matrix(block, 12))


_STEPS = ctypes.CFUNCTYPE(None, ctypes.c_int64, ctypes.c_void_p)(_physics_steps_c.address)


class StepCall:
    """``StepCall(args)(n)`` = ``physics_steps(n, *args)`` for ``args`` of
    :meth:`Simulation.physics_step_args`, through the C entry point where every array is
    C-contiguous float64 of the kernel's dimensions (else through numba's dispatcher).  Keeps
    ``args`` (and so the memory the block points into) alive as long as it is."""

    def __init__(self, args: tuple):
        self.args = args
        self.block = self._block(args)
        self.address = None if self.block is None else self.block.ctypes.data

    @staticmethod
    def _block(args: tuple):
        fns, model_addr, data_addr, *arrays = args
        if len(arrays) != len(NDIM) or fns.dtype != np.uint64 or fns.shape != (6,) or not fns.flags.c_contiguous:
            return None
        block = [fns.ctypes.data, int(model_addr), int(data_addr)]
        for a, ndim in zip(arrays, NDIM):
            if a.dtype != np.float64 or not a.flags.c_contiguous or a.ndim != ndim:
                return None
            block += [a.ctypes.data, a.shape[0], a.shape[1] if ndim == 2 else 0]
        return np.array(block, np.int64)

    def __call__(self, n: int):
        if self.address is None:
            physics_steps(n, *self.args)
        else:
            _STEPS(n, self.address)


#: dimensions of the arrays among them: commands, command, spool, spool_position, hysteresis,
#: rows, leak_s, leak_e, areas (the block's first entry points at (lo, hi, slip, leak_width))
COMMAND_NDIM = (1, 1, 1, 1, 1, 2, 1, 1, 2)


@numba.cfunc(types.int64(types.CPointer(types.int64)), cache=True, error_model="numpy")
def _command_step_c(block):
    scalars = numba.carray(_f64_pointer(block[0]), (4,))
    return command_step(_vector(block, 0), scalars[0], scalars[1], scalars[2], _vector(block, 1),
                        _vector(block, 2), _vector(block, 3), _vector(block, 4), _matrix(block, 5),
                        _vector(block, 6), _vector(block, 7), scalars[3], _matrix(block, 8))


_COMMAND = ctypes.CFUNCTYPE(ctypes.c_int64, ctypes.c_void_p)(_command_step_c.address)


class CommandCall:
    """``CommandCall(args)(u)`` = ``command_step(u, *args)`` for ``args`` of
    :meth:`Simulation.command_step_args` and ``u`` (n,) float64 commands [V]: ``u`` is copied
    into a buffer the block points at, then the C entry point runs (the dispatcher where an
    array is not C-contiguous float64).  Keeps ``args`` alive as long as it is."""

    def __init__(self, args: tuple):
        self.args = args
        lo, hi, slip, command, spool, spool_position, hysteresis, rows, leak_s, leak_e, leak_width, areas = args
        self.commands = np.zeros(command.shape)
        self.scalars = np.array([lo, hi, slip, leak_width], float)
        arrays = (self.commands, command, spool, spool_position, hysteresis, rows, leak_s, leak_e, areas)
        block = [self.scalars.ctypes.data, 0, 0]
        for a, ndim in zip(arrays, COMMAND_NDIM):
            if a.dtype != np.float64 or not a.flags.c_contiguous or a.ndim != ndim:
                self.block = self.address = None
                return
            block += [a.ctypes.data, a.shape[0], a.shape[1] if ndim == 2 else 0]
        self.block = np.array(block, np.int64)
        self.address = self.block.ctypes.data

    def __call__(self, u: np.ndarray) -> int:
        if self.address is None:
            return command_step(u, *self.args)
        self.commands[:] = u
        return _COMMAND(self.address)
