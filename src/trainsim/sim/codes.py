"""Codes and indices shared by the compiled kernels of the single-point model (``sim/_kernel_c.pyx``,
``_energy_c``, ``_trace_c``, ``optimize/_pmp_c``) and their callers: regimes, the layout of the
parameter vector P, tolerances, statuses and the integrators' settings."""

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
#: ``_kernel_c.fastest_segment(..., grow=True)``: the out arrays are full, run the segment again with
#: longer ones (never a run's status).
STATUS_FULL = 2

# Settings of the compiled integrators (sim/_kernel_c.pyx, sim/_forces.pxd hold the same values; a test
# checks that they agree).

#: Longest RK4 step as a share of the motion's length scale 2E / |a| = v^2 / |a| [-] (within about
#: that distance E(s) meets the square-root singularity of standstill), at most ``MAX_SUBSTEPS``
#: sub-steps per step. Only slow, strongly braked or accelerated steps are divided: at 20 m/s and
#: 1 m/s^2 the scale is 400 m.
LENGTH_SCALE_FRACTION = 0.01
MAX_SUBSTEPS = 64
#: Sub-intervals of a step over which time is summed with the exact constant-acceleration formula.
TIME_SUBSTEPS = 4
#: Speed change covered by one RK4 step of a speed-domain integration [m/s], and the fewest steps.
SPEED_DOMAIN_STEP = 0.05
SPEED_DOMAIN_MIN_STEPS = 3
#: Extra steps per unit of |ln(a_end / a_start)|: a force that changes steeply with speed (source
#: 002's braking force, 150 to 335 kN between 5 and 6 km/h) puts a pole of ds/dv = v / a(v) close to
#: the interval, where a nearly constant one (most tables) needs only the fewest steps.
SPEED_DOMAIN_STEPS_PER_LOG = 12.0
#: Most RK4 steps of one speed-domain integration.
SPEED_DOMAIN_MAX_STEPS = 128
#: Near standstill (a step that the distance domain would divide into ``SLOW_STEP_SUBSTEPS`` sub-steps
#: or more), the fastest run integrates its steps in the speed domain (accelerating, braking backwards
#: from a stop, and braking forwards unless the step ends below half its start speed): RK4 in at
#: least ``SLOW_STEP_SPEED_STEPS`` steps to the speed a constant acceleration would reach, then at
#: most ``SLOW_STEP_NEWTON`` Newton steps on the end speed until the step's length is met to
#: ``SLOW_STEP_TOLERANCE`` relative (``sim/_kernel_c.pyx``, ``speed_domain_step``). From 32 sub-steps
#: on, every figure of the examples stays within 5.1e-10 of the distance domain's; from 8 on, running
#: times moved by up to 5.4e-9, where the distance domain's time over uniform sub-steps sized at the
#: step's slow start is the less accurate of the two (docs/reference/performance.md, "Stop 26").
SLOW_STEP_SUBSTEPS = 32
SLOW_STEP_SPEED_STEPS = 4
SLOW_STEP_NEWTON = 8
SLOW_STEP_TOLERANCE = 1e-13
