"""The jet-pipe controlled electropneumatic actuator of the Utah/MIT hand (paper 000).

Modules, one job each:
    params     fluid.toml -> JetpipeCfg (every field documented, SI)
    valve      current driver, tip force, static nonlinearity f3, third-order jet dynamics
    hysteresis Prandtl-Ishlinskii play operators (current -> jet position hysteresis)
    ports      receiver orifice areas from circle overlaps (closed form)
    chambers   orifice flows, piston leak, chamber pressures, force, steady pressures
    plant      the valve + chamber ODE and its RK4 step (numpy reference)
    kernel     the same step compiled with numba
    statics    the static force/current midpoint line f and its inverse
    linear     linearisation: poles, zeros, bandwidth (Table II, Fig. 21)
    freqresp   stepped-sine frequency responses
    sim        build() and JetpipeSim: MuJoCo and the fluid states stepped together
"""
