"""The multi-point model's kernel: its equations, its array layouts and its compiled functions.

Equations (source 000's multi-point model; one Newton equation per vehicle, i = 0 at the head)::

    rho_i m_i dv_i/dt = T_(i-1) - T_i + F_i(v_i) - B_i(v_i) - R_i(v_i) - m_i g lambda_i(x_i, v_i)
    dx_i/dt = v_i

with T_k the tension of coupling k (between vehicles k and k+1) as a function of its extension
delta_k = x_k - L_k - x_(k+1) and its rate, F_i the traction of a locomotive, B_i the braking force,
R_i the running resistance and lambda_i the specific gradient, curve and tunnel resistance averaged
over the vehicle's own length.

Integrator: the implicit midpoint rule. With the midpoint velocities w = (v0 + v1) / 2 as unknowns,
x1 = x0 + h w and the residual ``2 M (w - v0) / h - F(x0 + h w / 2, w) = 0`` has a symmetric
tridiagonal Jacobian ``2M/h + D + (h/2) K + C`` (K, C: coupler stiffness and damping, D: derivative of
the vehicles' own forces), solved by Newton iterations with the Thomas algorithm: O(n) per iteration. A step whose Newton
iterations do not converge (``MAX_NEWTON``; given up earlier when the damped iterations cannot reach
the tolerance in time, ``HOPELESS_MARGIN``) is halved.
The rule is A-stable (any coupler stiffness is stable at any step) and symplectic: it neither adds
nor removes energy from the coupler oscillations, so losses come from the dampers alone, and the
kinetic energy change of a step equals the work of the midpoint forces exactly, which the energy
accounting uses.

Dry friction (running resistance, brakes) is regularised: it opposes motion through tanh(v / v_eps),
so a vehicle at rest is held by a stiff viscous law instead of a switch, which the implicit scheme
integrates without small steps.

The functions are compiled (Cython, ``multipoint/_mp_c.pyx``, built by ``pip install .``); this module
defines the columns of the arrays they read and write and re-exports them: ``run`` (integrate until a
time or an event), ``record`` (store a state), ``implicit_step`` (one step's Newton solve),
``vehicle_forces``, ``coupler_force``,
``coupler_energy``, ``thomas`` and ``tanh``. Importing it loads no numba (issue 14).
"""

from __future__ import annotations

from trainsim.multipoint._mp_c import (
    coupler_energy,
    coupler_force,
    implicit_step,
    record,
    run,
    tanh,
    thomas,
    vehicle_forces,
)

__all__ = [
    "coupler_energy",
    "coupler_force",
    "implicit_step",
    "record",
    "run",
    "tanh",
    "thomas",
    "vehicle_forces",
]

# columns of the vehicle parameter array VP
V_MASS = 0  # static mass m_i [kg]
V_INERTIAL = 1  # rho_i m_i [kg]
V_LENGTH = 2  # length over couplers [m]
V_R0 = 3  # running resistance c0 [N]
V_R1 = 4  # c1 [N s/m]
V_R2 = 5  # c2 [N s^2/m^2]
V_BRAKE = 6  # share of the friction brake [-]
V_REGEN = 7  # share of the electric brake [-]
V_CURVE = 8  # index of the traction curve in the curve bank, -1 for unpowered vehicles
V_PROFILE = 9  # index of the line-resistance profile (by vehicle length)
V_DELAY = 10  # delay of the brake command [s]
N_V = 11

# columns of the coupler parameter array CP
C_KD = 0  # draft stiffness [N/m]
C_KB = 1  # buff stiffness [N/m]
C_CD = 2  # draft damping [N s/m]
C_CB = 3  # buff damping [N s/m]
C_HALF_SLACK = 4  # half the free slack [m]
C_TD = 5  # draft travel [m]
C_TB = 6  # buff travel [m]
C_KS = 7  # solid stiffness [N/m]
C_EPS = 8  # smoothing width [m]
C_MU = 9  # friction ratio of the draft gears: loading (1 + mu) x, unloading (1 - mu) x the spring [-]
C_VF = 10  # regularisation speed of the gears' friction [m/s]
N_C = 11

# scalar parameters SP
S_STEP = 0  # largest time step [s]
S_VEPS = 1  # standstill regularisation speed [m/s]
S_BRAKE_FRACTION = 2  # share of the service braking force used [-]
S_DECEL = 3  # constant service deceleration [m/s^2], 0 for a braking force law
S_BUILD_UP = 4  # brake cylinder time constant [s]
S_TAU = 5  # time constant of the speed controller [s]
S_LOOKAHEAD = 6  # anticipation time of the brake delay [s]
S_REST_SPEED = 7  # every vehicle slower than this: the train is at rest [m/s]
S_STOP_WINDOW = 8  # a stop counts within this distance [m]
S_RECORD_DT = 9  # record interval [s]
S_ETA_T = 10  # traction efficiency [-]
S_ETA_R = 11  # regenerative efficiency x receptivity [-]
S_SERVICE_CURVE = 12  # index of the service braking curve in the bank
S_REGEN_CURVE = 13  # index of the regenerative braking curve, -1 without
S_G = 14  # gravity [m/s^2]
S_STALL_S = 15  # at rest in traction this long: stalled [s]
S_NEWTON_TOL = 16  # Newton tolerance on the midpoint speeds [m/s]
S_TRACK_PROFILE = 17  # 1: in traction follow the reference speed; 0: full traction up to the ceiling
S_RAMP = 18  # time to raise the traction command from 0 to full [s], 0: at once
S_STEP_MIN = 19  # smallest step [s]
S_FORCE_TOL = 20  # tolerance of the coupler-force error estimate per step [N], 0: fixed steps
N_S = 21

# command array CMD: friction brake level, blend flag, signed command for the record, then per vehicle
# traction level (N) and electric brake level (N)
K_FRICTION = 0
K_BLEND = 1
K_COMMAND = 2
K_REGIME = 3
N_K = 4

# accumulators ACC (cumulative works [J], energies [J])
A_TRACTION = 0
A_FRICTION = 1
A_ELECTRIC = 2
A_RUNNING = 3
A_GRADIENT = 4
A_CURVE = 5
A_TUNNEL = 6
A_DAMPER = 7
A_SPRING_WORK = 8  # work of the spring forces (= -change of spring energy, up to the step error)
A_HELD = 9  # kinetic energy removed when the train is declared at rest (counted as braking)
N_WORKS = 10  # A_TRACTION .. A_HELD are recorded
A_PEAK_POWER = 10  # largest line-side power (before auxiliaries) since the last record [W]
A_SUBSTEPS = 11  # steps halved because Newton did not converge
A_NEWTON = 12  # Newton iterations
A_STEPS = 13  # steps
A_REST_SINCE = 14  # time since when the train is at rest in traction [s], -1 when moving
A_H = 15  # size of the next step [s]
A_NMEM = 16  # number of step-end coupler forces remembered (up to 3)
A_REJECTED = 17  # steps repeated shorter for the force tolerance
A_LAST_H = 18  # length of the last step [s]
A_INTEGRATED = 19  # time integrated (excluding dwells) [s]
N_A = 20

# aggregated record columns REC_AGG
R_HEAD = 0
R_SPEED = 1  # inertial-mass-weighted mean speed [m/s]
R_COMMAND = 2
R_REGIME = 3
R_TRACTION = 4  # total traction force [N]
R_ELECTRIC = 5  # total electric braking force [N]
R_FRICTION = 6  # total friction braking force [N]
R_RUNNING = 7
R_GRADIENT = 8
R_CURVE = 9
R_TUNNEL = 10
R_TRACTION_POWER = 11  # sum of F_i v_i [W]
R_ELECTRIC_POWER = 12  # sum of E_i v_i [W]
R_PEAK_POWER = 13  # largest line-side power since the previous record [W] (before auxiliaries)
R_KINETIC = 14  # kinetic energy [J]
R_SPRING = 15  # energy stored in the coupler springs [J]
R_W0 = 16  # first cumulative work column: the accumulators A_TRACTION .. A_HELD follow
N_R = R_W0 + N_WORKS

# extremes EXT: the train's largest draft and buff force, then (when EXT is long enough) per coupling
# k, at N_E + N_EK k: its largest draft force, when, where the head was, its largest buff force, when,
# where the head was
E_DRAFT, E_DRAFT_K, E_DRAFT_T, E_DRAFT_HEAD, E_BUFF, E_BUFF_K, E_BUFF_T, E_BUFF_HEAD = range(8)
N_E = 8
EK_DRAFT, EK_DRAFT_T, EK_DRAFT_HEAD, EK_BUFF, EK_BUFF_T, EK_BUFF_HEAD = range(6)
N_EK = 6

# status codes
ST_TIME = 0  # reached the end time
ST_STOPPED = 1  # at rest at the stop
ST_STALLED = 2
ST_RECORD_FULL = 3
ST_HISTORY_FULL = 4
ST_FAILED = 5  # Newton failed even on the smallest sub-step
ST_END_OF_ROUTE = 6

#: Below this speed the electric (regenerative) brake fades linearly to 0 at standstill and the
#: friction brakes take over its share [m/s]: an electric brake cannot hold a train at rest, and
#: without the fade the locomotives would hold the whole train while the wagons roll away from them.
ELECTRIC_FADE_MPS = 1.0
#: Newton iterations per (sub-)step before halving.
MAX_NEWTON = 12
#: From this iteration on (counted from 0) Newton takes half updates: next to a kink of a force law
#: (slack taken up, the draft gears' friction) full updates can cycle.
DAMPED_FROM = 6
#: The damped iterations halve the update at best, so an update of iteration ``it`` above
#: ``HOPELESS_MARGIN * tol * 2**(MAX_NEWTON - 1 - it)`` (from iteration DAMPED_FROM + 1) cannot reach the
#: tolerance ``tol`` in time: the step is halved at once rather than after MAX_NEWTON iterations (issue 14).
HOPELESS_MARGIN = 64.0
