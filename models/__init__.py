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


def available() -> list[str]:
    """Names of the models that ship with pneumasim."""
    return sorted(p.name for p in ROOT.iterdir() if (p / "fluid.toml").is_file())


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
