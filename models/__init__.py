"""Robot models: one folder per robot with ``<name>.xml`` (MJCF), ``scene.xml``,
``fluid.toml`` (fluid-power parameters) and a README.

This loader only finds files; :func:`pneumatics.robot.load_robot` builds the simulator model.
"""
from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parent


class UnknownModelError(KeyError):
    def __init__(self, name: str):
        self.name = name
        super().__init__(f"unknown model {name!r}; valid: {', '.join(available())}")

    def __str__(self) -> str:
        return self.args[0]


VALVE_ARM = "valve_arm"
"""The kind of the Kokoro-valve robots (arm2, humanoid38) that :func:`pneumatics.robot.load_robot`
builds; other kinds (``jetpipe``, ``hydraulic``, ``bench``) have their own builders."""


def available(kind: str | None = None) -> list[str]:
    """Names of the models that ship with pneumasim; only those of ``kind`` if given."""
    names = sorted(p.name for p in ROOT.iterdir() if (p / "fluid.toml").is_file())
    return [n for n in names if kind is None or model_kind(n) == kind]


def model_kind(name: str) -> str:
    """The top-level ``kind = "..."`` of the model's fluid.toml (default ``valve_arm``)."""
    import tomllib

    doc = tomllib.loads(fluid_path(name).read_text())
    return str(doc.get("kind", VALVE_ARM))


def folder(name: str) -> Path:
    """The model's folder; :class:`UnknownModelError` lists the valid names."""
    path = ROOT / name
    if not (path / "fluid.toml").is_file():
        raise UnknownModelError(name)
    return path


def mjcf_path(name: str, scene: bool = False) -> Path:
    return folder(name) / ("scene.xml" if scene else f"{name}.xml")


def fluid_path(name: str) -> Path:
    return folder(name) / "fluid.toml"
