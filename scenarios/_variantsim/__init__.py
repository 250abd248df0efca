"""An independent arm2 simulator ("variantsim-1") with hidden effects in functional forms other
than pneumasim's, for judging the doctor on physics it was not written against.

Written from the arm2 reference numbers (reference/arm2.md beside DESIGN.md) and paper 002
only; imports nothing from
pneumatics/, identification/, controllers/ or models/.  ``kernel`` (numba fluid + friction
step), ``arm`` (config, MJCF, 10 ms rows), ``control`` (PIDF, reference, recording, restarted
replays), ``effects`` (the variant forms), ``cases`` (concealed cases + truth.json).
See docs/doctor_variants.md.
"""
