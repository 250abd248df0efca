"""humanoid38's MJCF, written from the link table (:mod:`.design`) and the sized actuators."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .design import (
    EXCLUDE,
    Gear,
    Geom,
    LINKS,
    Link,
    MODEL,
    PELVIS,
    PELVIS_HEIGHT,
    Rotary,
    SEGMENT_FRACTION,
    TOTAL_MASS_KG,
    Tendon,
    link_mass,
    shape_inertia,
    tendon_sites,
)


# -- MJCF --------------------------------------------------------------------------------
def _f(x) -> str:
    """A number as MJCF text: short and exact enough (5 significant digits, no -0)."""
    s = f"{float(x):.5g}"
    return "0" if s in ("-0", "0") else s


def _v(xs) -> str:
    return " ".join(_f(x) for x in xs)


@dataclass
class JointDyn:
    damping: float = 0.1
    armature: float = 1e-4


def _geom_xml(g: Geom, cls: str) -> str:
    attrs = [f'class="{cls}"', f'type="{g.type}"', f'size="{_v(g.size)}"']
    if g.fromto is not None:
        attrs.append(f'fromto="{_v(g.fromto)}"')
    elif any(g.pos):
        attrs.append(f'pos="{_v(g.pos)}"')
    if cls == "visual":
        attrs.append(f'material="{g.material}"')
    return f"<geom {' '.join(attrs)}/>"


def _geoms_xml(geoms) -> list[str]:
    out = [_geom_xml(g, "visual") for g in geoms]
    out += [_geom_xml(g, "collision") for g in geoms if g.collide]
    return out


def build_mjcf(dyn: dict[str, JointDyn], phases: dict[str, float] | None = None,
               actuators: dict | None = None) -> str:
    """The MJCF text; ``dyn`` gives joint damping/armature, ``phases`` the tendon levers'
    phase (default pi/2) and ``actuators`` the comment on each actuator."""
    tendon_links = [l for l in LINKS if isinstance(l.drive, Tendon)]
    site_of = _cylinder_sites(tendon_links, phases)
    return _document(_worldbody(dyn, site_of), tendon_links, actuators)


def _cylinder_sites(tendon_links, phases) -> dict[str, list[str]]:
    """body -> the <site> lines of the cylinders pinned to it (base on the parent, rod on the child)."""
    site_of: dict[str, list[str]] = {}
    for link in tendon_links:
        base, rod = tendon_sites(link, (phases or {}).get(link.joint, math.pi / 2))
        site_of.setdefault(link.parent, []).append(
            f'<site class="cylinder" name="{link.joint}_cyl_base" pos="{_v(base)}"/>')
        site_of.setdefault(link.body, []).append(
            f'<site class="cylinder" name="{link.joint}_cyl_rod" pos="{_v(rod)}"/>')
    return site_of


def _worldbody(dyn, site_of) -> list[str]:
    """The <body> tree from the pelvis down, one line each."""
    children: dict[str, list[Link]] = {}
    for link in LINKS:
        children.setdefault(link.parent, []).append(link)

    def inertial(mass, com, shape):
        return (f'<inertial pos="{_v(com)}" mass="{_f(mass)}" '
                f'diaginertia="{_v(shape_inertia(mass, shape))}"/>')

    def body(link: Link, depth: int) -> list[str]:
        ind = "  " * depth
        lo, hi = np.radians(link.range_deg)
        d = dyn[link.joint]
        lines = [f'{ind}<body name="{link.body}" pos="{_v(link.pos)}">',
                 f'{ind}  <joint name="{link.joint}" axis="{_v(link.axis)}" range="{_f(lo)} {_f(hi)}" '
                 f'damping="{_f(d.damping)}" armature="{_f(d.armature)}"/>',
                 f'{ind}  {inertial(link_mass(link), link.com, link.shape)}']
        lines += [f"{ind}  {g}" for g in _geoms_xml(link.geoms)]
        lines += [f'{ind}  <site class="marker" name="{n}" pos="{_v(p)}"/>' for n, p in link.sites]
        lines += [f"{ind}  {s}" for s in site_of.get(link.body, [])]
        for child in children.get(link.body, []):
            lines += body(child, depth + 1)
        lines.append(f"{ind}</body>")
        return lines

    pelvis_mass = TOTAL_MASS_KG * SEGMENT_FRACTION["trunk"] * PELVIS["mass_share"]
    tree = ['    <body name="pelvis" pos="0 0 %s" childclass="%s">' % (_f(PELVIS_HEIGHT), MODEL),
            f'      {inertial(pelvis_mass, PELVIS["com"], PELVIS["shape"])}']
    tree += [f"      {g}" for g in _geoms_xml(PELVIS["geoms"])]
    tree += [f"      {s}" for s in site_of.get("pelvis", [])]
    for child in children["pelvis"]:
        tree += body(child, 3)
    tree.append("    </body>")
    return tree


def _document(tree: list[str], tendon_links, actuators) -> str:
    """The whole MJCF file around the body tree: defaults, tendons, actuators, sensors, keyframe
    (most of its length is the file's literal text)."""
    tendons = [f'    <spatial name="{l.joint}_cyl" class="{MODEL}">\n'
               f'      <site site="{l.joint}_cyl_base"/>\n      <site site="{l.joint}_cyl_rod"/>\n'
               f"    </spatial>" for l in tendon_links]
    acts = []
    for link in LINKS:
        note = f"  <!-- {actuators[link.joint]} -->" if actuators else ""
        if isinstance(link.drive, Tendon):
            acts.append(f'    <motor name="{link.joint}" tendon="{link.joint}_cyl"/>{note}')
        else:
            gear = 1.0 if isinstance(link.drive, Rotary) else link.drive.r
            acts.append(f'    <motor name="{link.joint}" joint="{link.joint}" gear="{_f(gear)}"/>{note}')
    sensors = [f'    <jointpos name="q.{l.joint}" joint="{l.joint}"/>' for l in LINKS]
    home = " ".join(_f(math.radians(l.home_deg)) for l in LINKS)
    excludes = [f'    <exclude body1="{a}" body2="{b}"/>' for a, b in EXCLUDE]
    n_vane = sum(isinstance(l.drive, Rotary) for l in LINKS)
    n_gear = sum(isinstance(l.drive, Gear) for l in LINKS)
    return f"""<!--
  humanoid38: a fixed-base, child-sized pneumatic humanoid with 38 joints, in the spirit of
  Kokoro's Diego-San (paper 002 section VI).  GENERATED by generate.py: edit that, then run
  `python -m models.humanoid38.generate`.  See README.md.

  x forward, y left, z up; the pelvis is welded to the world at {_f(PELVIS_HEIGHT)} m (the robot
  stands on a stand).  One hinge per body, at the body origin.  Every joint has one
  double-acting actuator, named after the joint, a plain force actuator whose ctrl the fluid
  layer writes every step (models/humanoid38/fluid.toml):
    {n_vane} rotary vanes        <motor joint gear="1">   ctrl = torque [N m]
    {n_gear} cylinders, fixed arm <motor joint gear="r">   ctrl = force [N], r = moment arm [m]
    {len(tendon_links)} cylinders on pins   <motor tendon>          ctrl = force [N] along the
                                                    pin-to-pin tendon <joint>_cyl; its
                                                    length grows with the joint angle
-->
<mujoco model="{MODEL}">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.001" gravity="0 0 -9.81"/>

  <default>
    <default class="{MODEL}">
      <joint type="hinge" limited="true" solreflimit="0.01 1"/>
      <motor ctrllimited="false"/>
      <site group="4"/>
      <tendon width="0.004" rgba="0.85 0.65 0.15 1"/>
      <default class="visual">
        <geom contype="0" conaffinity="0" group="2" density="0"/>
      </default>
      <default class="collision">
        <geom group="3" density="0" rgba="0.8 0.3 0.3 0.3"/>
      </default>
      <default class="cylinder">
        <site size="0.006" rgba="0.85 0.65 0.15 1"/>
      </default>
      <default class="marker">
        <site size="0.01" rgba="0.9 0.3 0.1 1"/>
      </default>
    </default>
  </default>

  <asset>
    <material name="shell" rgba="0.88 0.88 0.9 1"/>
    <material name="joint" rgba="0.22 0.22 0.25 1"/>
  </asset>

  <worldbody>
{chr(10).join(tree)}
  </worldbody>

  <contact>
{chr(10).join(excludes)}
  </contact>

  <tendon>
{chr(10).join(tendons)}
  </tendon>

  <actuator>
{chr(10).join(acts)}
  </actuator>

  <sensor>
{chr(10).join(sensors)}
  </sensor>

  <keyframe>
    <key name="home" qpos="{home}"/>
  </keyframe>
</mujoco>
"""
