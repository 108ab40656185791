"""Codes and indices shared by every compiled kernel of the single-point model and its callers:
regimes, the layout of the parameter vector P, tolerances and statuses. Free of numba, so that what
only needs the codes does not load the numba kernels."""

from __future__ import annotations

TRACTION = 0
CRUISE = 1
COAST = 2
BRAKE = 3
DWELL = 4
REGEN = 5  # maximum regenerative braking only (no friction brakes), used by energy-efficient driving
FOLLOW = 6  # following a given speed profile: the forces are what its accelerations need

REGIME_NAMES = ("traction", "cruising", "coasting", "braking", "dwell", "regenerative braking", "following")

# Indices into the scalar parameter vector P.
P_INERTIAL_MASS = 0  # rho m [kg]
P_MASS = 1  # static mass m [kg]; the track's line-resistance laws are per unit mass [N/kg]
P_WEIGHT = P_MASS  # former name (m g when the track held ratios of the weight)
P_R0 = 2  # running resistance c0 [N]
P_R1 = 3  # c1 [N s/m]
P_R2 = 4  # c2 [N s^2/m^2]
P_DECEL = 5  # constant service deceleration [m/s^2], 0 when braking is a force law
P_BRAKE_FRACTION = 6  # share of the service braking force used [-]
# Share of the tractive effort available in the interval being integrated (0 on a non-electrified
# part for an electric train). It changes per interval, so the walkers set it before each interval
# rather than threading one more argument through every integrator.
P_TRACTION_SCALE = 7
N_PARAMS = 8

#: Two speeds closer than this are the same speed [m/s] (far below any physical meaning).
SPEED_TOLERANCE = 1e-7
#: Root-finding stops when the bracket is shorter than this [m].
POSITION_TOLERANCE = 1e-9

STATUS_OK = 0
STATUS_STALLED = 1
