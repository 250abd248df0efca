"""Declarative, validated configuration: dataclass fields that carry doc, unit and range.

Every fluid-power parameter is a dataclass field made with :func:`spec`; :func:`from_table`
builds the dataclass from a TOML table and rejects, with one line naming file and field,
unknown fields (with the closest valid name, so ``bore_mm`` points at ``bore_m``), missing
required fields, wrong types and values outside the plausible range (a bore of 20 "m" is
a bore in mm).
"""
from __future__ import annotations

import dataclasses
import difflib
import math
from typing import Any

from .errors import ConfigError


def read_toml(path, what: str = "fluid-power file") -> dict:
    """A TOML file as a dict; a missing file or bad TOML is a ConfigError naming the file."""
    import tomllib
    from pathlib import Path

    path = Path(path)
    try:
        return tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise ConfigError(f"{path}: {what} not found") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: not valid TOML: {e}") from None

_REQUIRED = dataclasses.MISSING


def spec(default: Any = _REQUIRED, doc: str = "", unit: str = "-", lo: float | None = None,
         hi: float | None = None):
    """A dataclass field with documentation, SI unit and plausible range [lo, hi]."""
    meta = {"doc": doc, "unit": unit, "lo": lo, "hi": hi}
    if default is _REQUIRED:
        return dataclasses.field(metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def describe(cls) -> str:
    """One line per field: name, unit, range, doc (for READMEs and error messages)."""
    out = []
    for f in dataclasses.fields(cls):
        m = f.metadata
        rng = f" [{m.get('lo')}, {m.get('hi')}]" if m.get("lo") is not None else ""
        out.append(f"{f.name} ({m.get('unit', '-')}){rng}: {m.get('doc', '')}")
    return "\n".join(out)


def from_table(cls, table: dict, where: str, *, defaults: dict | None = None,
               nested: dict | None = None):
    """Build dataclass ``cls`` from TOML ``table``; ``where`` names it in errors.

    ``defaults`` supplies values for fields the table omits; ``nested`` maps a field name to a
    callable that turns its sub-table into the field's value.
    """
    if not isinstance(table, dict):
        raise ConfigError(f"{where}: expected a table, got {type(table).__name__}")
    names = {f.name: f for f in dataclasses.fields(cls)}
    nested = nested or {}
    kwargs = {}
    for key, value in table.items():
        if key not in names:
            close = difflib.get_close_matches(key, names, n=1, cutoff=0.5)
            hint = f" (did you mean {close[0]!r}, in {names[close[0]].metadata.get('unit', '-')}?)" if close else ""
            raise ConfigError(f"{where}: unknown field {key!r}{hint}; valid: {', '.join(names)}")
        f = names[key]
        if key in nested:
            kwargs[key] = nested[key](value, f"{where}.{key}")
            continue
        kwargs[key] = _check_value(f, value, where)
    for key, f in names.items():
        if key in kwargs:
            continue
        if defaults and key in defaults:
            kwargs[key] = defaults[key]
        elif f.default is _REQUIRED and f.default_factory is _REQUIRED:
            unit = f.metadata.get("unit", "-")
            raise ConfigError(f"{where}: missing field {key!r} ({unit}): {f.metadata.get('doc', '')}")
    return cls(**kwargs)


def _check_value(f, value, where):
    meta = f.metadata
    lo, hi, unit = meta.get("lo"), meta.get("hi"), meta.get("unit", "-")
    if lo is None and hi is None:
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{where}.{f.name}: expected a number in {unit}, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(f"{where}.{f.name}: expected a finite number in {unit}, got {value!r}")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise ConfigError(
            f"{where}.{f.name} = {value:g} is outside the plausible range [{lo:g}, {hi:g}] {unit}"
            f" (is it in the wrong unit?)")
    return value
