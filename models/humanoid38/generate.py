"""Generate the humanoid38 model: ``humanoid38.xml`` (MJCF) and ``fluid.toml`` (fluid power).

humanoid38 is a fixed-base, child-sized (1.34 m, 28 kg) humanoid with 38 pneumatic joints in
the spirit of Kokoro's Diego-San (paper 002 §VI: 38 DOFs without the hands, one double-acting
cylinder or vane per joint, two valves and two pressure sensors per actuator, 76 controls).
The paper gives no dimensions, so everything here is a plausible design derived from a few
stated rules.  This script writes both files, and the joint table of ``README.md``, from the
tables of ``design.py`` (loads and sizes by ``sizing.py``, the MJCF by ``mjcf.py``), so every
number is derived and reproducible
(``python -m models.humanoid38.generate``; random draws come from ``SEED``).

What is derived, in order:

1. **Link masses** -- a 28 kg total split over body segments by fractions close to human ones
   (Winter's adult table, with more mass in the limbs, where a pneumatic robot carries its
   cylinders, and less in the trunk), then over the links of each segment.
2. **Link inertias** -- each link's mass spread over a solid box, cylinder or sphere of the
   link's size, about a centre of mass given per link.
3. **Cylinder geometry** -- a *tendon* joint is driven by a cylinder pinned to the parent link
   at distance ``a`` from the joint axis and to a lever of length ``b`` on the child link.  The
   pin-to-pin length grows monotonically over the whole range (chamber ``a`` extends the
   cylinder and turns the joint positive) and the moment arm ``a b sin(phi) / L`` never
   vanishes, because the lever angle phi stays inside (0.2, pi - 0.2); the lever's phase is
   chosen to minimise the force the joint needs (step 4).  A *gear* joint has a constant moment
   arm; a *rotary* joint a vane.
4. **Loads** -- MuJoCo computes, over random poses inside the joint ranges, each joint's
   gravity torque and its diagonal inertia; a joint needs ``max(1.5 x gravity, 10 rad/s^2 x
   inertia, 0.1 N m)``, divided by the moment arm at that pose (MuJoCo's actuator length,
   differentiated) for a cylinder.  In the home pose it also needs an air spring (both
   chambers sealed at 4 bar) that holds the gravity load within 4 deg and is 1.5 times stiffer
   than gravity's destabilising slope (inverted pendulums: waist, neck).
5. **Actuator sizes** -- the smallest ISO bore (with its ISO rod) whose rod-side annulus makes
   that force at 6 bar (7 bar supply, 1 bar room) and whose air spring is stiff enough; a
   vane's displacement likewise.  Strokes (vane travels) cover the joint's travel plus 4 mm
   (0.1 rad) and are rounded up to 5 mm (0.05 rad); the piston clears both end stops by the same
   margin over the whole range.  Dead volumes (port and tube) are 0.5 cm^3 + 10 % of the swept
   volume, kept in 0.5-5 cm^3.
6. **Joint damping and armature** -- seal friction grows with the actuator (0.5 % of its
   6-bar torque per rad/s, kept in 0.05-0.5 N m s/rad); armature is the steel rod and
   aluminium piston reflected through the mean moment arm (a vane: 1e-4 kg m^2), kept in
   1e-4-1e-3 kg m^2.
7. **Valves** -- the valve's effective area scales with its chamber's volume at mid-stroke,
   anchored at arm2's shoulder (15 cm^3 -> 8e-7 m^2 supply, 9e-7 m^2 exhaust), so every
   chamber fills with about arm2's time constant, kept in 1.5e-7-2e-6 m^2; then every one of
   the 76 valves gets its own draw: both areas x U(0.85, 1.15) (one factor per valve), null
   5 V + U(-0.15, 0.15) V, null-leak fraction U(0.015, 0.03), dead band U(0.1, 0.25) V,
   opening exponent U(1.1, 1.5).
8. **Sensors** -- arm2's noise after averaging, times sqrt(500/200): the humanoid's DAQ
   averages 200 samples per period instead of 500 (paper 002 §II).

Conventions: x forward, y left, z up; at q = 0 the robot stands straight with the arms
hanging and the palms facing the thighs, and every body frame is aligned with the world.  The
pelvis is welded to the world at 0.75 m (the robot stands on a stand).  Every body but the
pelvis has exactly one hinge, at its origin.  Sagittal joints turn positive in flexion (waist
and neck bend forward, head nods down, arm and thigh swing forward, elbow and knee bend,
ankle dorsiflexes, toes curl down, jaw opens); limb roll joints are positive in abduction
(ankle: eversion, clavicle: elevation), limb yaw joints in external rotation (forearm:
supination, wrist yaw: radial deviation); trunk and neck roll and yaw follow the right-hand
rule about x and z.  The right side mirrors the left (positions y -> -y, axes (x, y, z) ->
(-x, y, -z)), so a joint and its twin have the same range, the same sign convention and the
same actuator.
"""
from __future__ import annotations

import argparse
import math
import re

import mujoco
import numpy as np

from .design import (
    ARM2_ANGLE_NOISE,
    ARM2_PRESSURE_NOISE,
    DP_PA,
    HERE,
    LINKS,
    MODEL,
    NOISE_SCALE,
    NULL_SCATTER_V,
    NULL_V,
    ROOM_PA,
    SEED,
    SUPPLY_PA,
    Tendon,
    VALVE_AREA_RANGE,
    VALVE_EXHAUST_RATIO,
    VALVE_EXPONENT,
    VALVE_REF_SUPPLY_M2,
    VALVE_REF_VOLUME,
    VALVE_SCATTER,
    rotation,
)
from .mjcf import JointDyn, build_mjcf
from .sizing import Sizing, best_phase, joint_dynamics, lengths_over_range, sample_loads, size_actuators


# -- valves and TOML ---------------------------------------------------------------------
def valve_tables(sizes: list[Sizing]) -> list[tuple[dict, dict]]:
    """Step 7: base areas from the actuator's displacement, then one random draw per valve."""
    rng = np.random.default_rng(SEED)
    out = []
    for s in sizes:
        volume = s.dead_volume + 0.5 * s.extras["swept_m3"]  # chamber a at mid-stroke
        base = VALVE_REF_SUPPLY_M2 * (volume / VALVE_REF_VOLUME) ** VALVE_EXPONENT
        base = float(np.clip(base, *VALVE_AREA_RANGE))
        pair = []
        for _ in "ab":
            scale = rng.uniform(1 - VALVE_SCATTER, 1 + VALVE_SCATTER)
            pair.append({
                "supply_area_max_m2": base * scale,
                "exhaust_area_max_m2": base * VALVE_EXHAUST_RATIO * scale,
                "null_v": NULL_V + rng.uniform(-NULL_SCATTER_V, NULL_SCATTER_V),
                "null_leak_fraction": rng.uniform(0.015, 0.03),
                "deadband_v": rng.uniform(0.10, 0.25),
                "opening_exponent": rng.uniform(1.1, 1.5),
            })
        s.extras["valve_base_m2"] = base
        out.append(tuple(pair))
    return out


def _t(x, digits=4) -> str:
    """A TOML float with ``digits`` significant digits, written like 1.25e-6 or 0.035."""
    mantissa, _, exponent = f"{x:.{digits}g}".partition("e")
    if "." not in mantissa:
        mantissa += ".0"
    return f"{mantissa}e{int(exponent)}" if exponent else mantissa


def build_toml(sizes: list[Sizing], valves) -> str:
    lines = [
        "# humanoid38 fluid-power parameters.  GENERATED by generate.py (see README.md): edit",
        "# that and run `python -m models.humanoid38.generate`.  Every field is documented in",
        "# pneumatics/{medium,params,valve,actuator}.py; SI units, pressures absolute.",
        "# Actuators are in the MJCF's actuator order; chamber a turns the joint positive.",
        "",
        "[gas]                              # as arm2: air, adiabatic chambers (002 eq. 9)",
        "gas_constant_j_per_kg_k = 287.0",
        "heat_capacity_ratio = 1.4",
        "temperature_k = 293.15",
        "polytropic_exponent = 1.4",
        "laminar_ratio = 0.995",
        "",
        "[supply]",
        f"supply_pa = {_t(SUPPLY_PA)}                  # 7 bar compressor",
        f"room_pa = {_t(ROOM_PA)}                    # 1 bar room",
        "",
        "[control]",
        "rate_hz = 100.0                    # 100 Hz loop, as the arm (002 §II)",
        "",
        "[sensors]                          # 200 samples at 20 kHz averaged (002 §II): arm2's",
        f"angle_noise_rad = {_t(ARM2_ANGLE_NOISE * NOISE_SCALE, 3)}          # noise (500 samples) x sqrt(500/200)",
        f"pressure_noise_pa = {_t(ARM2_PRESSURE_NOISE * NOISE_SCALE, 3)}",
        "average = true",
        "",
        "[valve]                            # shared shape; every valve overrides its own below",
        "half_range_v = 5.0",
        "null_leak_width_v = 0.6",
    ]
    for s, (va, vb) in zip(sizes, valves):
        link = s.link
        lo, hi = link.range_deg
        lines += ["", "[[actuator]]", f'name = "{link.joint}"']
        if s.kind == "rotary":
            lines += [
                'kind = "rotary"',
                f"displacement_m3_per_rad = {_t(s.displacement, 2)}  # {s.capacity:.3g} N m at 6 bar; "
                f"needs {s.need:.3g}",
                f"travel_rad = {_t(s.stroke, 3)}{' ' * 19}# range {lo:g}..{hi:g} deg",
            ]
        else:
            how = (f"pins, moment arm {1e3 * s.moment_min:.1f}-{1e3 * s.extras['moment_max']:.1f} mm"
                   if s.transmission == "tendon" else f"moment arm {1e3 * s.moment_mean:.0f} mm")
            lines += [
                'kind = "linear"',
                f"bore_m = {_t(s.bore_mm / 1e3)}{' ' * 22}# {how}; needs {s.need:.0f} N",
                f"rod_m = {_t(s.rod_mm / 1e3)}",
                f"stroke_m = {_t(s.stroke, 3)}{' ' * 20}# range {lo:g}..{hi:g} deg moves the piston "
                f"{1e3 * (s.length_span[1] - s.length_span[0]):.1f} mm",
            ]
        lines += [
            f"dead_volume_a_m3 = {_t(s.dead_volume, 3)}",
            f"dead_volume_b_m3 = {_t(s.dead_volume, 3)}",
            f"position_at_zero = {_t(s.position_at_zero, 4)}",
        ]
        for tag, v in (("a", va), ("b", vb)):
            lines.append(f"[actuator.valve_{tag}]")
            lines += [f"{k} = {_t(x, 4)}" for k, x in v.items()]
    return "\n".join(lines) + "\n"


# -- README table --------------------------------------------------------------------------
TABLE_BEGIN, TABLE_END = "<!-- joint table: generated -->", "<!-- end of joint table -->"


def readme_table(sizes: list[Sizing], dyn: dict[str, JointDyn]) -> str:
    rows = ["| # | joint | range [°] | home [°] | actuator | transmission | size | stroke / travel "
            "| torque at 6 bar [N·m] | worst gravity [N·m] | damping | armature |",
            "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for i, s in enumerate(sizes):
        link = s.link
        lo, hi = link.range_deg
        if s.kind == "rotary":
            act, trn = "rotary vane", "joint, gear 1"
            size, stroke = f"D = {s.displacement * 1e6:.3g} cm³/rad", f"{math.degrees(s.stroke):.0f}°"
            torque = f"{s.capacity:.3g}"
        else:
            size, stroke = f"Ø{s.bore_mm}/{s.rod_mm} mm", f"{1e3 * s.stroke:.0f} mm"
            force = s.area_b * DP_PA  # the weaker (rod) side
            if s.transmission == "joint":
                act, trn = "cylinder", f"joint, r = {1e3 * s.moment_mean:.0f} mm"
                torque = f"{force * s.moment_mean:.3g}"
            else:
                act = "cylinder"
                trn = f"pins, r = {1e3 * s.moment_min:.0f}–{1e3 * s.extras['moment_max']:.0f} mm"
                torque = f"{force * s.moment_min:.3g}–{force * s.extras['moment_max']:.3g}"
        d = dyn[link.joint]
        rows.append(f"| {i} | `{link.joint}` | {lo:g} … {hi:g} | {link.home_deg:g} | {act} | {trn} | {size} "
                    f"| {stroke} | {torque} | {s.tau_gravity:.2g} | {d.damping:g} | {d.armature:.2g} |")
    return "\n".join(rows)


def update_readme(table: str):
    path = HERE / "README.md"
    if not path.is_file():
        return
    text = path.read_text()
    pattern = re.compile(re.escape(TABLE_BEGIN) + ".*?" + re.escape(TABLE_END), re.S)
    if pattern.search(text):
        path.write_text(pattern.sub(lambda _: f"{TABLE_BEGIN}\n{table}\n{TABLE_END}", text))


# -- checks ------------------------------------------------------------------------------
def check(model: mujoco.MjModel, sizes: list[Sizing]):
    """Home pose inside the ranges, no contact at home, every piston inside its stroke over
    its joint's range, and MuJoCo's pin-to-pin lengths equal to :func:`tendon_length`'s."""
    data = mujoco.MjData(model)
    for s in sizes:
        if s.transmission != "tendon":
            continue
        link = s.link
        jid = model.joint(link.joint).id
        qs, L = lengths_over_range(model, data, model.actuator(link.joint).id,
                                    model.jnt_qposadr[jid], *model.jnt_range[jid], n=11)
        base = model.site_pos[model.site(f"{link.joint}_cyl_base").id]
        rod = model.site_pos[model.site(f"{link.joint}_cyl_rod").id]
        n = np.asarray(link.axis, float)
        ours = [np.linalg.norm(np.asarray(link.pos) + rotation(n, q) @ rod - base) for q in qs]
        assert np.allclose(L, ours, atol=1e-9), link.joint
    key = model.key("home")
    lo, hi = model.jnt_range.T
    assert np.all((key.qpos > lo) & (key.qpos < hi)), "home pose outside a joint range"
    mujoco.mj_resetDataKeyframe(model, data, key.id)
    mujoco.mj_forward(model, data)
    assert data.ncon == 0, f"{data.ncon} contacts in the home pose"
    for s in sizes:
        x0 = s.length_span[0] - s.length_zero + s.position_at_zero
        x1 = s.length_span[1] - s.length_zero + s.position_at_zero
        assert 0 < x0 < x1 < s.stroke, (s.link.joint, x0, x1, s.stroke)
        assert 0 <= s.position_at_zero <= s.stroke


def lowest_point(model: mujoco.MjModel) -> float:
    """Lowest collision-geom point [m] in the home pose (the floor is at z = 0)."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    low = np.inf
    for g in range(model.ngeom):
        if model.geom_group[g] != 3:
            continue
        # sample the geom's surface by its AABB corners in its own frame
        half = model.geom_aabb[g, 3:]
        centre = model.geom_aabb[g, :3]
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half + centre
        world = corners @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
        low = min(low, world[:, 2].min())
    return float(low)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quiet", action="store_true", help="print nothing")
    args = parser.parse_args(argv)

    provisional = {l.joint: JointDyn() for l in LINKS}
    loads = sample_loads(mujoco.MjModel.from_xml_string(build_mjcf(provisional)))
    phases = {l.joint: best_phase(l, loads[l.joint]) for l in LINKS if isinstance(l.drive, Tendon)}
    sizes = size_actuators(mujoco.MjModel.from_xml_string(build_mjcf(provisional, phases)), loads)
    dyn = joint_dynamics(sizes)
    valves = valve_tables(sizes)
    notes = {}
    for s in sizes:
        if s.kind == "rotary":
            notes[s.link.joint] = f"vane {s.displacement * 1e6:.3g} cm3/rad"
        else:
            notes[s.link.joint] = f"cylinder {s.bore_mm}/{s.rod_mm} mm x {1e3 * s.stroke:.0f} mm"
    xml = build_mjcf(dyn, phases, notes)
    final = mujoco.MjModel.from_xml_string(xml)
    check(final, sizes)
    (HERE / f"{MODEL}.xml").write_text(xml)
    (HERE / "fluid.toml").write_text(build_toml(sizes, valves))
    update_readme(readme_table(sizes, dyn))

    if not args.quiet:
        mass = final.body_subtreemass[final.body("pelvis").id]
        d = mujoco.MjData(final)
        mujoco.mj_resetDataKeyframe(final, d, final.key("home").id)
        mujoco.mj_forward(final, d)
        top = max(d.geom_xpos[g, 2] + final.geom_rbound[g] for g in range(final.ngeom))
        print(f"{MODEL}: {final.njnt} joints, {final.nu} actuators, {final.ntendon} tendons, "
              f"mass {mass:.2f} kg, height {top:.3f} m, lowest collision point {lowest_point(final):.3f} m")
        for s in sizes:
            size = (f"D {s.displacement * 1e6:7.3g} cm3/rad" if s.kind == "rotary"
                    else f"bore {s.bore_mm:2d}/{s.rod_mm:2d} mm")
            print(f"  {s.link.joint:26s} {s.transmission:6s} {size:20s} stroke {s.stroke:.3f} "
                  f"x0 {s.position_at_zero:.4f}  gravity {s.tau_gravity:6.2f} N m  "
                  f"capacity {s.capacity:6.2f} N m  dead {s.dead_volume * 1e6:.2f} cm3  "
                  f"valve {s.extras['valve_base_m2']:.2e} m2")


if __name__ == "__main__":
    main()
