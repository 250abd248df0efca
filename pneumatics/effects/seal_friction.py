"""Rod-seal friction of a linear cylinder and the load-cell offset (coulomb_friction,
viscous_friction, force_sensor_offset for bench cylinders).

Friction force [N] on a rod moving at v [m/s], per direction, Coulomb part growing with the
chamber gauge pressure (the seal is pressed harder against the rod: e.g. Belforte, Mattiazzo,
Mauro & Tokashiki, "Measurement of friction force in pneumatic cylinders", Tribotest 10, 2003;
Nouri, Al-Bender, Swevers, Vanherck & Van Brussel, "Modelling a pneumatic servo positioning
system with friction", ACC 2000)::

    F_f(v) = s+(v) (Fc+ + kc+ p_g) - s-(v) (Fc- + kc- p_g) + b+ v+ + b- v-

with s+ = max(tanh(v / v_eps), 0), s- = max(-tanh(v / v_eps), 0), v+ = max(v, 0),
v- = min(v, 0), p_g = p - p_room.  It is positive in the direction of v: the force the rod
drive must add to move the rod against the seal.  A load cell that reads
``true + offset_n`` adds the same value in both directions — a symmetric friction plus an
offset equals an asymmetric Coulomb friction, which is why one constant-speed run cannot tell
the two apart.
"""
from __future__ import annotations

import numpy as np

SMOOTH_M_S = 1e-3
"""v_eps [m/s] of the tanh that replaces sign(v) (1 mm/s; the bench drives at ~10 mm/s)."""


def direction_shapes(v, smooth_m_s: float = SMOOTH_M_S):
    """(s+, s-) >= 0 of velocities v (N,): how much the rod moves out (+) or in (-)."""
    s = np.tanh(np.asarray(v, float) / smooth_m_s)
    return np.maximum(s, 0.0), np.maximum(-s, 0.0)


def seal_friction(v, gauge_pa=0.0, coulomb_pos_n=0.0, coulomb_neg_n=0.0, viscous_pos_n_s_m=0.0,
                  viscous_neg_n_s_m=0.0, coulomb_per_pa_pos=0.0, coulomb_per_pa_neg=0.0,
                  smooth_m_s: float = SMOOTH_M_S):
    """Friction [N] along v (N,) at chamber gauge pressure ``gauge_pa`` (float or (N,))."""
    v = np.asarray(v, float)
    sp, sn = direction_shapes(v, smooth_m_s)
    return (sp * (coulomb_pos_n + coulomb_per_pa_pos * gauge_pa)
            - sn * (coulomb_neg_n + coulomb_per_pa_neg * gauge_pa)
            + viscous_pos_n_s_m * np.maximum(v, 0.0) + viscous_neg_n_s_m * np.minimum(v, 0.0))


def load_cell_reading(true_force_n, offset_n: float = 0.0, gain: float = 1.0):
    """What a load cell with a zero offset [N] (force_sensor_offset) and a gain error reads."""
    return gain * np.asarray(true_force_n, float) + offset_n
