"""Physical constants and unit conversion factors: the only place they are defined.

Everything inside trainsim is SI (m, s, kg, N, W, J). Multiply a value given in the unit named on
the left by the factor to get SI; divide an SI value by it to get the named unit.
"""

from __future__ import annotations

#: Standard acceleration due to gravity [m/s^2] (CGPM 1901; ISO 80000-3): the default of
#: ``Route.gravity_mps2``. Gravity is a setting of the route, never a literal in the physics.
STANDARD_GRAVITY = 9.80665

#: Gravity conventions of the sources trainsim reads [m/s^2]; each reader sets its source's value
#: on the routes (and the weight-based resistance laws) it builds.
#: railtoolkit / TrainRuns.jl (``g = 9.80665`` in its formulary).
TRAINRUNS_GRAVITY = 9.80665
#: TTOBench and ms-eetc (``g = 9.81``).
TTOBENCH_GRAVITY = 9.81
#: NREL ALTRIOS (``uc::ACC_GRAV = 9.80155``, its value for the continental United States).
ALTRIOS_GRAVITY = 9.80155

#: Plausible gravity at the Earth's surface [m/s^2]: 9.78 at the equator, 9.83 at the poles;
#: the allowed range of ``Route.gravity_mps2`` leaves a margin around it.
GRAVITY_RANGE_MPS2 = (9.7, 9.9)

#: Legacy name: TTOBench / ms-eetc's 9.81 [m/s^2]. Kept only for code outside the simulation core
#: (plots, web previews) that has no route at hand; the core takes gravity from the route.
G = TTOBENCH_GRAVITY

#: Density of air at 15 degC, sea level [kg/m^3] (ISA).
AIR_DENSITY = 1.225

KMH = 1.0 / 3.6  #: km/h -> m/s
TONNE = 1000.0  #: t -> kg
KN = 1000.0  #: kN -> N
KW = 1000.0  #: kW -> W
MW = 1.0e6  #: MW -> W
KWH = 3.6e6  #: kWh -> J
PERMILLE = 1.0e-3  #: per mille (N/kN, m/km) -> dimensionless ratio
MINUTE = 60.0  #: min -> s

#: Reference speed v00 of the per-mille resistance laws of Strahl, Sauthoff and Wende [m/s]
#: (Wende 2003, p. 151-153; TrainRuns.jl ``v00 = 100/3.6``).
WENDE_REFERENCE_SPEED = 100 * KMH
#: Head-wind allowance dv_air added to the speed in the air term of Sauthoff's and Wende's laws [m/s]
#: (Wende 2003; TrainRuns.jl ``Δv_air = 15/3.6``).
WENDE_AIR_SPEED_MARGIN = 15 * KMH
