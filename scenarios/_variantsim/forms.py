"""The variant simulator's form registry: for every effect family, several published
functional forms, each with its place kind, source, a draw of physical magnitudes and how the
concealment scale k acts on it.  ``FORMS`` maps family -> forms; the forms themselves live in
:mod:`.forms_joint`, :mod:`.forms_chamber` and :mod:`.forms_supply`.

Families: the DESIGN.md vocabulary except ``force_sensor_offset`` (arm2's recordings carry no
force sensor column, so no offset of one can show in them), plus ``outside_vocabulary``:
physics the vocabulary has no name for, at a chamber, a joint or the supply.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from .arm import CHAMBERS, JOINTS

#: the place kinds a form can sit at, and the place names of each
PLACES = {"joint": list(JOINTS), "chamber": list(CHAMBERS), "actuator": list(JOINTS), "supply": ["all"]}
OUTSIDE = "outside_vocabulary"


@dataclass(frozen=True)
class Form:
    """One functional form of one family.

    ``draw(rng, ctx)`` returns its physical parameters at full magnitude (ctx: ``reach_rad``,
    joint -> (lowest, highest) reference angle of the main recording); ``apply(col, e,
    hidden)`` switches it on at place column ``col`` with effective parameters ``e``;
    ``scaled`` keys are multiplied by the concealment scale k, ``inverse`` keys divided by it
    (a time scale that shrinks, an area that opens), the rest are shapes; a ``contribution``
    form gets ``contribution_scale`` = k (its term in dp/dt times k); ``slots`` name the
    simulator elements it occupies at its place (two effects never share one)."""

    family: str
    name: str
    kind: str
    source: str
    summary: str
    draw: Callable
    apply: Callable
    scaled: tuple = ()
    inverse: tuple = ()
    contribution: bool = False
    slots: tuple = field(default_factory=tuple)

    def effective(self, params: dict, k: float) -> dict:
        """The parameters at concealment scale k."""
        out = {}
        for key, v in params.items():
            out[key] = v * k if key in self.scaled else v / k if key in self.inverse else v
        if self.contribution:
            out["contribution_scale"] = k
        return out

    def scale_rule(self) -> str:
        parts = []
        if self.scaled:
            parts.append(", ".join(self.scaled) + " × k")
        if self.inverse:
            parts.append(", ".join(self.inverse) + " ÷ k")
        if self.contribution:
            parts.append("its dp/dt term × k")
        return "; ".join(parts)


def _registry() -> dict[str, list[Form]]:
    from .forms_chamber import CHAMBER_FORMS
    from .forms_joint import JOINT_FORMS
    from .forms_supply import SUPPLY_FORMS

    out: dict[str, list[Form]] = {}
    for f in JOINT_FORMS + CHAMBER_FORMS + SUPPLY_FORMS:
        out.setdefault(f.family, []).append(f)
    return out


#: family -> its forms (the first is the one variantsim-1 used, where it had one)
FORMS: dict[str, list[Form]] = _registry()
#: the vocabulary families this simulator draws (every key of FORMS but outside_vocabulary)
FAMILIES: tuple[str, ...] = tuple(f for f in FORMS if f != OUTSIDE)


def form_of(family: str, name: str | None = None) -> Form:
    """The form ``name`` of ``family`` (its first form when name is None); a clear error
    naming the known ones otherwise."""
    if family not in FORMS:
        raise ValueError(f"variant simulator: unknown effect family {family!r}; known: {', '.join(FORMS)}")
    forms = FORMS[family]
    if name is None:
        return forms[0]
    for f in forms:
        if f.name == name:
            return f
    raise ValueError(f"variant simulator: family {family!r} has no form {name!r}; "
                     f"its forms: {', '.join(f.name for f in forms)}")


def place_column(kind: str, place: str) -> int:
    """The kernel column of a place."""
    return 0 if kind == "supply" else PLACES[kind].index(place)


def where(kind: str, place: str) -> dict:
    """The place as DESIGN.md's report ``where``."""
    if kind == "chamber":
        a, c = place.split(".")
        return {"actuator": a, "chamber": c}
    return {"actuator": place} if kind == "actuator" else {"supply": "all"} if kind == "supply" else {"joint": place}


def forms_table() -> str:
    """The markdown table family | form | place | what | source | concealment scale."""
    lines = ["| family | form | place | what | source | concealment scale k |",
             "| --- | --- | --- | --- | --- | --- |"]
    for fam, forms in FORMS.items():
        for f in forms:
            lines.append(f"| {fam} | `{f.name}` | {f.kind} | {f.summary} | {f.source} | {f.scale_rule()} |")
    return "\n".join(lines) + "\n"
