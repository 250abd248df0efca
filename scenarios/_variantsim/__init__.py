"""An independent arm2 simulator ("variantsim-6") with hidden effects in several published
functional forms per family, for judging the doctor on physics it was not written against.

Written from the arm2 reference numbers (reference/arm2.md beside DESIGN.md), paper 002 and
the sources each form names; imports nothing from pneumatics/, identification/,
controllers/ or models/.  ``rows`` (the kernel's parameter and state rows), ``flows``,
``mechanics`` and ``kernel`` (numba: flow laws, joint torques, the 1 ms step), ``hysteresis``
(valve hysteresis operators), ``arm`` (config, MJCF, 10 ms rows, dead time, sensor models),
``control`` (PIDF, reference, recording, restarted replays), ``forms`` with ``forms_joint``,
``forms_chamber``, ``forms_supply`` (the form registry), ``effects`` (effects -> Hidden),
``cases`` (concealed cases + truth.json).  See docs/doctor_variants.md and
docs/effects_variants.md.
"""
