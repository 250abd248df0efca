"""Recordings of humanoid38 with hidden physics: the cases of
scenarios/doctor_benchmark_humanoid38.py.

A case = a seed -> no effect, one, or two of different families (family and place drawn at
random among the places of the family's kind on humanoid38: 76 chambers, 38 joints or
actuators, the supply), +-3 % errors in the nominal parameters and the sensor noise of
fluid.toml's ``[sensors]``.  The parameter errors are those of the arm2 case maker
(scenarios/_cases.py, :func:`perturbed_robot`), applied to every actuator and body of
humanoid38: each valve's supply and exhaust areas, each chamber's dead volume, each body's
mass and inertia (one factor per body).

**Concealment** (kept simple, no search): a hidden effect's parameters are the family's own
draw (``Family.draw``: the magnitudes the arm2 case maker starts its concealment halving from)
times a scale drawn uniformly in CONCEAL_SCALE = [0.25, 0.5], i.e. one to two of arm2's
halvings.  humanoid38's actuators are arm2's kind (cylinders and vanes, valve areas within a
factor of five of arm2's), so such an effect is small against the whole robot yet meant to
show on its own chamber or joint.  Whether it is
concealed (the nominal model's held-out R^2 >= 0.9) is not checked: on 76 chambers the
restarted replays cost about as much as the doctor (docs/humanoid_doctor.md).  Only a recording
the doctor's reading checks would refuse is made again with the effects halved (MAX_HALVINGS).

The robot tracks one of humanoid38's standard references under the calibrated PIDF (what
scenarios/humanoid38_tracking.py does with the fast valve calibration): the controller and the
doctor know the nominal robot, the simulator runs the perturbed one.
"""
from __future__ import annotations

import functools

import numpy as np

from pneumatics.effects.family import place_names
from pneumatics.errors import RecordingError, UnknownNameError
from pneumatics.robot import load_robot

from ._cases import BENCHMARK_FAMILIES, effects_of, perturbed_valves, truth_of

MODEL = "humanoid38"
PARAM_ERROR = 0.03
CONCEAL_SCALE = (0.25, 0.5)
MAX_HALVINGS = 4
"""A recording the doctor's reading checks refuse (a joint far outside its range: MuJoCo's soft
limit gave way where a real stop holds; a chamber reading below zero absolute: a transducer
offset no absolute sensor can show) is made again with the effects halved, at most this many
times; a null case's is an error."""


def humanoid_families() -> list[str]:
    """The benchmark families the simulator can place on humanoid38 (``Family.places``)."""
    robot = load_robot(MODEL)
    from pneumatics.effects.registry import get_family

    return [f for f in BENCHMARK_FAMILIES if get_family(f).places(robot)]


#: parts of humanoid38 (the other joints locked at the home pose, pneumatics.robot_subset): the
#: doctor-time plot's points between arm2's 4 chambers and the whole robot's 76
_LEFT_ARM = ("left_clavicle_elevation", "left_shoulder_pitch", "left_shoulder_roll", "left_shoulder_yaw",
             "left_elbow", "left_forearm_roll", "left_wrist_pitch", "left_wrist_yaw")
_ARMS = _LEFT_ARM + tuple(n.replace("left_", "right_") for n in _LEFT_ARM)
SUBSETS = {
    "left_arm": _LEFT_ARM,
    "arms": _ARMS,
    "upper_body": ("waist_yaw", "waist_pitch", "waist_roll", "neck_yaw", "neck_pitch", "neck_roll", "head_pitch",
                   "jaw") + _ARMS,
}


def nominal_humanoid(subset: str | None = None):
    """humanoid38, or the part of it named ``subset`` (a key of SUBSETS)."""
    robot = load_robot(MODEL)
    if subset is None:
        return robot
    from pneumatics.robot_subset import restricted_robot

    if subset not in SUBSETS:
        raise UnknownNameError("humanoid38 subset", subset, list(SUBSETS))
    return restricted_robot(robot, SUBSETS[subset], subset)


def perturbed_humanoid(rng: np.random.Generator, fraction: float = PARAM_ERROR, subset: str | None = None):
    """humanoid38 (or its part ``subset``) with every valve area, dead volume and body mass (with
    its inertia) off by up to +-fraction (scenarios/_cases.py's arm2 errors, on every actuator
    and body)."""
    robot = nominal_humanoid(subset)
    f = lambda: float(1 + rng.uniform(-fraction, fraction))  # noqa: E731
    robot = perturbed_valves(robot, f)
    factors = {}
    for i in range(1, robot.model.nbody):  # body 0 is the world
        if robot.model.body_mass[i] > 0:
            s = f()
            factors[f"mass_and_inertia.{robot.model.body(i).name}"] = s
            robot.model.body_mass[i] *= s
            robot.model.body_inertia[i] *= s
    return robot, factors


def draw_on_humanoid(family: str, rng: np.random.Generator, robot):
    """(family, place, parameters): ``family`` at a random place of its kind on humanoid38 that
    the simulator can put it at (``Family.places``: a backlash needs a joint-transmission
    actuator).  The place is drawn among all places of the kind first, and again among the
    possible ones only when the first draw is not one of them, so a case whose first draw
    stands keeps the draws it had before the restriction."""
    from pneumatics.effects.registry import get_family

    fam = get_family(family)
    places = place_names(robot, fam.place_kind)
    place = places[int(rng.integers(0, len(places)))]
    possible = fam.places(robot)
    if place not in possible:
        place = possible[int(rng.integers(0, len(possible)))]
    return fam, place, fam.draw(rng)


@functools.lru_cache(maxsize=2)
def controller(subset: str | None = None):
    """(PIDF cfg, valve linearizer, references) of the nominal humanoid38 (or its part
    ``subset``: the references of its joints), once per process."""
    from controllers.reference import JointReference, standard_references

    from ._humanoid import calibrated_linearizer, pidf_gains, range_test

    robot = nominal_humanoid(subset)
    lin, _, _ = calibrated_linearizer(robot, True)
    cfg = pidf_gains(range_test(robot, lin, one_at_a_time=False))
    refs = standard_references(MODEL, "normal")
    if subset is not None:
        cols = [refs[0].joint_names.index(n) for n in robot.joint_names]
        refs = [JointReference(r.time, r.q[:, cols], list(robot.joint_names), r.lam) for r in refs]
    return cfg, lin, refs


def refusal(robot, *recordings) -> str | None:
    """Why the doctor's reading checks (pneumatics.recording_checks.check_for_robot) would refuse
    one of ``recordings`` of ``robot``, or None."""
    import warnings

    from pneumatics.recording_checks import check_for_robot

    for rec in recordings:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                check_for_robot(rec, robot)
        except RecordingError as e:
            return str(e)
    return None


def make_case(seed: int, families: list[str], seconds: float, heldout_seconds: float, subset: str | None = None,
              given: list[dict] | None = None):
    """(main recording, held-out recording, truth dict) of one case of humanoid38 (or of its part
    ``subset``); the held-out recording tracks a different reference with a different noise seed.
    ``given``: effects placed as stated instead of drawn ([{"family", "place", "parameters"
    (the form's fields), "form" (optional)}], e.g. an issue's example), at their own magnitude."""
    from .humanoid38_tracking import track

    rng = np.random.default_rng(seed)
    nominal = nominal_humanoid(subset)
    if given:
        drawn = [_given_effect(g, nominal) for g in given]
        families = [fam.name for fam, _, _ in drawn]
        scale = 1.0
    else:
        drawn = [draw_on_humanoid(f, rng, nominal) for f in families]
        scale = float(rng.uniform(*CONCEAL_SCALE)) if families else 1.0
    robot, factors = perturbed_humanoid(rng, subset=subset)
    cfg, lin, refs = controller(subset)
    k = int(rng.integers(0, len(refs)))
    for halvings in range(MAX_HALVINGS + 1):
        effects = effects_of(drawn, scale)
        main = track(robot, cfg, refs[k], lin, seconds, seed=2 * seed + 1, effects=effects)
        held = track(robot, cfg, refs[(k + 1) % len(refs)], lin, heldout_seconds, seed=2 * seed + 2, effects=effects)
        refused = refusal(nominal, main, held)
        if refused is None:
            break
        if not families or given or halvings == MAX_HALVINGS:
            raise RecordingError(f"{nominal.name} case {seed}: the doctor would refuse its recording "
                                 f"({refused}){' with the effects halved ' + str(halvings) + ' times' if halvings else ''}")
        scale *= 0.5
    truth = {"seed": seed, "model": nominal.name, "families": list(families) or ["none"], "effects": [truth_of(d, scale) for d in drawn],
             "scale": scale, "parameter_factors": factors, "perturbation_fraction": PARAM_ERROR,
             "references": [k, (k + 1) % len(refs)]}
    return main, held, truth


def _given_effect(g: dict, robot):
    """(family, place, parameters) of a stated effect (make_case's ``given``), its place checked."""
    from pneumatics.effects.registry import get_family

    fam = get_family(g["family"])
    possible = fam.places(robot)
    if g["place"] not in possible:
        raise UnknownNameError(f"{fam.name} place on {robot.name}", g["place"], possible)
    return fam, g["place"], fam.params(g["parameters"], g.get("form"))
