"""The hydraulic doctor's least-squares problem: residual channels (the oil replay's two chamber
pressures, the mechanical equation errors), their noise floors, the score J and the fits.

J = sum over channels of mean(r_c^2) / sigma_c^2 over the channel's scored samples, sigma_c the
channel's white-noise level estimated from the residual itself (third differences, robust:
:func:`identification.base.smoothing.noise_sd`; the smooth model error cancels).  The oil
replays are cached by the parameters they depend on, so a mechanical hypothesis costs no replay.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from identification.base import lsq
from identification.base.smoothing import noise_sd
from pneumatics.hydraulics.effects import HydraulicEffects

from .hypotheses import CAL_BOUND, CALIBRATION, DIFF_STEP, MECH_CAL, OIL_CAL, calibrated
from .mechanics import channel_masks, equation_errors
from .replay import hysteresis_output, replay_oil

OIL_FIELDS = ("hysteresis_extra_k0_a", "null_shift_a", "valve_leak_m3_per_pa_s", "vane_leak_m3_per_pa_s",
              "line_volume_extra_a_m3", "line_volume_extra_b_m3", "pump_droop_pa_s_per_m3", "pressure_sensor_offset_a_pa",
              "pressure_sensor_offset_b_pa", "angle_sensor_offset_rad")


class Problem:
    """The traces, the nominal parameters, the channels and their weights."""

    def __init__(self, cfg0, mech0, train, held):
        self.cfg0, self.mech0, self.train, self.held = cfg0, mech0, train, held
        mech = ["vane", "load"] if train[0].torque is not None else ["rigid"]
        brace = ["brace"] if train[0].torque is not None and any(t.braced for t in train) else []
        self.channels = ["p_a", "p_b", *mech, *brace]
        self.masks = {id(t): channel_masks(t, self.channels) for t in [*train, *held]}
        # a channel is scored only where both parts have samples of it (braced recordings alone: no load equation)
        self.channels = [c for c in self.channels if all(any(self.masks[id(t)][c].any() for t in part)
                                                         for part in (train, held))]
        self.sigma = {c: 1.0 for c in self.channels}
        self._oil_cache: dict = {}
        self._hyst_cache: dict = {}
        self.replays = 0

    # -- residuals --------------------------------------------------------------------------
    def oil(self, tr, dev, fx: HydraulicEffects) -> dict:
        """The oil replay of ``tr`` (cached by the oil calibration and the oil-side effects)."""
        # a braced trace's replay is driven by the shaft's twist rate (replay.vane_speed)
        compliance = 1.0 / self.mech0.k_s + fx.shaft_compliance_extra_rad_per_nm if tr.braced else None
        key = (id(tr), *(float(dev[k]) for k in OIL_CAL), *(getattr(fx, f) for f in OIL_FIELDS), compliance)
        if key not in self._oil_cache:
            if len(self._oil_cache) > 400:
                self._oil_cache.clear()
            cfg, _ = calibrated(self.cfg0, self.mech0, dev)
            k0 = cfg.hysteresis.k0_a + fx.hysteresis_extra_k0_a
            hk = (id(tr), k0)
            if hk not in self._hyst_cache:
                h = dataclasses.replace(cfg.hysteresis, k0_a=k0)
                self._hyst_cache[hk] = hysteresis_output(h, tr.current_a)
            self._oil_cache[key] = replay_oil(tr, cfg, fx, self._hyst_cache[hk], compliance)
            self.replays += 1
        return self._oil_cache[key]

    def sample_residuals(self, tr, dev, fx) -> dict:
        """channel -> (N,) measured - model (equation errors for the mechanical channels)."""
        pred = self.oil(tr, dev, fx)
        _, mech = calibrated(self.cfg0, self.mech0, dev)
        out = {"p_a": tr.p_a - pred["p_a"], "p_b": tr.p_b - pred["p_b"]}
        out.update(equation_errors(tr, mech, fx))
        for c in self.channels:  # a free trace has no brace channel: zeros, masked out
            out.setdefault(c, np.zeros(tr.time.size))
        return out

    def residuals(self, traces, dev, fx) -> dict:
        """channel -> (M,) residual over the channel's scored samples of all ``traces``."""
        out = {c: [] for c in self.channels}
        for tr in traces:
            r, m = self.sample_residuals(tr, dev, fx), self.masks[id(tr)]
            for c in self.channels:
                out[c].append(r[c][m[c]])
        return {c: np.concatenate(v) if v else np.zeros(0) for c, v in out.items()}

    def vector(self, traces, dev, fx) -> np.ndarray:
        r = self.residuals(traces, dev, fx)
        v = np.concatenate([r[c] / self.sigma[c] / np.sqrt(max(r[c].size, 1)) for c in self.channels])
        return np.where(np.isfinite(v), v, 1e6)

    def score(self, traces, dev, fx) -> tuple[float, dict]:
        """(J, per-channel mean square / sigma^2) on ``traces``."""
        r = self.residuals(traces, dev, fx)
        per = {c: float(np.mean(r[c] ** 2) / self.sigma[c] ** 2) for c in self.channels}
        return float(sum(per.values())), per

    def set_noise_floor(self, dev, fx):
        """sigma per channel: the white-noise level of the training residual (third differences)."""
        for c in self.channels:
            parts = [self.sample_residuals(t, dev, fx)[c][t.scored] for t in self.train if self.masks[id(t)][c].any()]
            self.sigma[c] = max(float(np.median([noise_sd(p) for p in parts])), 1e-9)

    def nrmse(self, traces, dev, fx, channel, masks=None) -> float:
        """NRMSE of ``channel`` on ``traces`` (normalised by the measured channel's s.d.; the
        mechanical channels by the s.d. of the hydraulic torque D_v (P_a - P_b))."""
        r = self.residuals(traces, dev, fx)[channel]
        ref = []
        for t in traces:
            m = self.masks[id(t)][channel]
            x = (t.p_a if channel == "p_a" else t.p_b if channel == "p_b" else t.torque / self.mech0.k_s
                 if channel == "brace" else self.mech0.d_v * (t.p_a - t.p_b))
            ref.append(x[m])
        return float(np.sqrt(np.mean(r ** 2)) / max(np.std(np.concatenate(ref)), 1e-300))


def effects_with(base: HydraulicEffects, hyps, values) -> HydraulicEffects:
    return dataclasses.replace(base, **{h.field: getattr(base, h.field) + v for h, v in zip(hyps, values)})


def fit(prob: Problem, hyps, x_eff, dev0, base: HydraulicEffects, sides=("oil", "mech"), max_nfev: int = 12):
    """Fit effect parameters (scaled) and the calibration deviations of ``sides`` together on
    the training traces; the other deviations stay at ``dev0``.  Returns (lsq.Fit, dev, fx):
    the Fit's values start with the effects' scaled parameters."""
    free = [k for k, (_, side) in enumerate(CALIBRATION) if side in sides]
    n = len(hyps)
    units = np.array([h.unit for h in hyps])
    lo = [h.lower / h.unit for h in hyps] + [-CAL_BOUND] * len(free)
    hi = [h.upper / h.unit for h in hyps] + [CAL_BOUND] * len(free)
    x0 = np.clip(np.concatenate([x_eff, np.asarray(dev0)[free]]), lo, hi)

    def unpack(x):
        dev = np.array(dev0, float)
        dev[free] = x[n:]
        return dev, effects_with(base, hyps, x[:n] * units)

    names = [h.name for h in hyps] + [CALIBRATION[k][0] for k in free]
    result = lsq.nonlinear(lambda x: prob.vector(prob.train, *unpack(x)), x0, names, lo, hi,
                           diff_step=DIFF_STEP, max_nfev=max_nfev)
    dev, fx = unpack(result.values)
    return result, dev, fx


def sides_of(hyps, braced: bool = False) -> tuple[str, ...]:
    """The calibration sides a fit of ``hyps`` needs (a mechanical effect leaves the oil replay
    alone, unless ``braced`` recordings make it drive the replay: ``Hypothesis.braced_side``)."""
    sides = {(h.braced_side or h.side) if braced else h.side for h in hyps}
    return ("oil", "mech") if not sides or "both" in sides else tuple(sorted(sides))


__all__ = ["MECH_CAL", "OIL_CAL", "Problem", "effects_with", "fit", "sides_of"]
