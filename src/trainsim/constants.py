"""Physical constants and unit conversion factors: the only place they are defined.

Everything inside trainsim is SI (m, s, kg, N, W, J). Multiply a value given in the unit named on
the left by the factor to get SI; divide an SI value by it to get the named unit.
"""

from __future__ import annotations

#: Acceleration due to gravity [m/s^2]. 9.81 rather than the standard 9.80665 because the
#: traction-calculation rules trainsim reproduces (TB/T 1407, Wende 2003, TrainRuns.jl) all use it.
G = 9.81

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
