"""Hidden effects of the variant simulator: an effect is {family, form, place, parameters};
this module turns a list of them at a concealment scale k into a :class:`~.arm.Hidden`.
The forms (several published ones per family, their sources, magnitude draws and how k acts)
are in :mod:`.forms`; ``docs/effects_variants.md`` tables them.

``force_sensor_offset`` is not drawn: arm2's recordings (DESIGN.md recording format, the
columns in :data:`.arm.COLUMNS`) carry no force sensor, so an offset of one cannot show in them.
"""
from __future__ import annotations

import numpy as np

from .arm import Hidden
from .forms import FAMILIES, FORMS, OUTSIDE, PLACES, Form, form_of, place_column, where  # noqa: F401 (re-exported)


def effective(family: str, params: dict, k: float, form: str | None = None) -> dict:
    """The parameters of ``family``'s ``form`` (its first form when None) at concealment scale k."""
    return form_of(family, form).effective(params, k)


def place_names(kind: str) -> list[str]:
    return list(PLACES[kind])


def apply(family: str, place: str, e: dict, hidden: Hidden, form: str | None = None) -> None:
    """Switch one effect with effective parameters ``e`` on in ``hidden``."""
    f = form_of(family, form)
    if place not in PLACES[f.kind]:
        raise ValueError(f"variant simulator: {family}/{f.name} sits at a {f.kind}; {place!r} is none of "
                         f"{', '.join(PLACES[f.kind])}")
    f.apply(place_column(f.kind, place), e, hidden)


def hidden_for(effects: list[dict], k) -> Hidden:
    """A Hidden with every effect ({family, form, place, parameters}; form optional) at
    concealment scale k: one scale for all, or a sequence of one scale per effect."""
    h = Hidden()
    scales = [float(k)] * len(effects) if np.isscalar(k) else list(k)
    for eff, ke in zip(effects, scales):
        form = eff.get("form")
        apply(eff["family"], eff["place"], effective(eff["family"], eff["parameters"], ke, form), h, form)
    return h
