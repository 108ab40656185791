"""One time step of the power network: assembly on sparse matrices and the nonlinear solution.

Nodal analysis: node potentials V [V] (earth = 0) satisfy Kirchhoff's current law

    G V + I_trains(V) = J_substations,

where G is the conductance (AC: admittance) matrix of the contact lines, rails, rail-to-earth
leakage and the substations' internal impedances, J the substations' Norton currents E / Z_i and
I_trains the trains' currents, constant-power loads and sources that depend on the pantograph
voltage u = V_contact - V_rail (EN 50388 traction limitation, regenerative curtailment):

    I_k = P_k(u) / u,   P_k(u) = P_traction a(u) + P_aux - P_regen r(u).

DC: Newton's method on this system (Jacobian G + dI/du stamps) with the step limited to 0.3 Un.
A diode rectifier's current ys max(E - U_s, 0) is rounded over a width d = DIODE_SMOOTHING_SHARE Un
(C1 piecewise quadratic, exactly 0 A once U_s > E + d), so that Newton does not cycle at the
switching point and a blocked rectifier takes and gives nothing; continuation through a reverse
conductance and starts on the curtailment or limitation ramps are the fallbacks (`solve_step`). AC: fixed-point iteration on the complex currents I_k = conj(S_k / u_k) with one LU
factorisation per step (simplified impedance model). Convergence is checked on every step.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from trainsim.errors import InputError

# the compiled parts (Cython, power/_solver_c.pyx); those marked noqa are not used here but kept under the
# names of the numba functions they replaced, where the tests find them
from trainsim.power._solver_c import assemble_dc_kernel as _assemble_dc_kernel
from trainsim.power._solver_c import band_solve as _band_solve  # noqa: F401
from trainsim.power._solver_c import dc_load_residual as _dc_load_residual
from trainsim.power._solver_c import dc_residual_full as _dc_residual_full  # noqa: F401
from trainsim.power._solver_c import diode_forward_scalar as _diode_forward_scalar  # noqa: F401
from trainsim.power._solver_c import diode_forward_slope_scalar as _diode_forward_slope_scalar  # noqa: F401
from trainsim.power._solver_c import half_bandwidth as _half_bandwidth  # noqa: F401
from trainsim.power._solver_c import newton_dc_core as _newton_dc_core  # noqa: F401
from trainsim.power._solver_c import newton_dc_dense as _newton_dc_dense
from trainsim.power._solver_c import relabel as _relabel  # noqa: F401
from trainsim.power._solver_c import stamp_dense as _stamp_dense  # noqa: F401
from trainsim.power._solver_c import stamp_pattern as _stamp_pattern
from trainsim.power.limits import (
    regen_acceptance,
    regen_acceptance_slope,
    traction_availability,
    traction_availability_slope,
)
from trainsim.power.network import Network
from trainsim.power.rail import _SMALL as _RAIL_SMALL
from trainsim.power.rail import leaky_rail_pi, segment_leakage_total_a
from trainsim.power.regulation import regulation_current_a

#: Newton / fixed point stop when no node potential moves by more than this share of Un
#: (7.5e-7 V at 750 V): far below any meaningful voltage, and the analytic tests need 1e-9.
VOLTAGE_TOLERANCE_SHARE = 1e-10
#: Largest Newton step, as a share of Un: keeps the first iterations of heavily loaded steps from
#: jumping to the non-physical low-voltage branch of a constant-power load.
MAX_STEP_SHARE = 0.3
MAX_NEWTON_ITERATIONS = 60
#: Newton iterations allowed from the previous step's potentials before the flat start is tried
#: (a warm start that has not converged by then is usually on the wrong rectifier branch).
WARM_START_ITERATIONS = 12
#: A diode rectifier blocks when its busbar is above E by more than this share of Un and conducts
#: again when below E by as much (7.5e-4 V at 750 V; the power at stake is this times a current
#: that is zero at the switching point).
RECTIFIER_MARGIN_SHARE = 1e-6
#: A diode rectifier's current is ys max(E - U, 0) rounded over this share of Un (d = 7.5 mV at 750 V)
#: by a C1 piecewise quadratic in x = E - U (:func:`_diode_forward`): 0 for x <= -d, ys (x + d)^2 / (4 d)
#: for |x| < d, ys x for x >= d. Newton no longer cycles when the solution sits at the switching point
#: (a rectifier at exactly E), I >= 0 always (a rectifier never takes power), and the rounding has a
#: finite tail: a rectifier whose busbar is more than d above E gives exactly 0 A. (A rounding with an
#: infinite tail, ys (x + sqrt(x^2 + d^2)) / 2, gave ys d^2 / (4 |x|) while blocking, a current that only
#: the 1e-9 S contact leakage took: an idle section floated hundreds of volts above E.)
DIODE_SMOOTHING_SHARE = 1e-5
#: Rounding of the corners of a wayside storage's power ramps, as a share of the ramp (0.2 V on a
#: 20 V ramp); a storage takes at most C d / 2 (1 % of its power) below its charging threshold.
STORAGE_ROUNDING = 1e-2
MAX_FIXED_POINT_ITERATIONS = 200
#: Positions are rounded to this [m] before nodes are built: two trains (or a train and a
#: substation) closer than 0.1 m share a node. Segments shorter than that would have conductances
#: above 1e5 S and make the nodal matrix too ill-conditioned for the tolerances below; 5 cm of
#: contact line is a few micro-ohms.
POSITION_RESOLUTION_M = 0.1
#: Kirchhoff residual accepted as converged, as a share of the substations' total short-circuit
#: current sum(E / R_i) (about 1e-5 A on a metro line): round-off of G V is well below it.
CURRENT_TOLERANCE_SHARE = 1e-10


@dataclass
class StepLoads:
    """What the trains on the wire ask for at one instant (one entry per train on the wire).

    Attributes:
        track: track index of each train.
        position_m: chainage [m].
        traction_w: traction power demanded at the pantograph before voltage limitation [W] (>= 0).
        regen_w: regenerated power offered to the line before curtailment [W] (>= 0).
        auxiliary_w: auxiliaries [W] (>= 0), drawn whatever the voltage.
        tan_phi: reactive / active power of each train (AC; 0 for DC) [-].
        storage_charge_max_w, storage_discharge_max_w: what each wayside storage of the network can
            take and give during this step (its power and its state of charge) [W]; None: nothing.
        train_ids: names of the trains, for error messages (None: named by their place).
    """

    track: np.ndarray
    position_m: np.ndarray
    traction_w: np.ndarray
    regen_w: np.ndarray
    auxiliary_w: np.ndarray
    tan_phi: np.ndarray
    storage_charge_max_w: np.ndarray | None = None
    storage_discharge_max_w: np.ndarray | None = None
    train_ids: tuple[str, ...] | None = None


@dataclass
class StepSolution:
    """Solution of one time step.

    Attributes:
        converged: whether the iteration met its tolerance (and the rectifier states settled).
        iterations: Newton / fixed-point iterations summed over the rectifier active-set passes.
        train_voltage_v: pantograph voltage magnitude of each train [V].
        train_power_w: active power at the pantograph (traction + aux - accepted regen) [W].
        train_current_a: current magnitude drawn (negative when feeding back) [A].
        traction_share: a(u) of each train [-]; regen_share: r(u) [-].
        substation_power_w: active power at each substation's busbar (negative: taken back) [W].
        substation_source_w: active power of each source E (busbar power + internal losses) [W].
        substation_current_a: current of each substation (signed, DC; magnitude x sign(P) AC) [A].
        substation_on: rectifier state.
        line_loss_w: losses in contact lines, rails and leakages [W]: ``contact_loss_w +
            return_loss_w``.
        substation_loss_w: losses in the substations' internal resistances [W]: the sources' power
            less the busbars' (``substation_source_w - substation_power_w`` summed).
        contact_loss_w: losses in the contact lines and the contact-to-return leakage [W] (AC: the
            loop impedance, contact line and return together).
        return_loss_w: losses in the return (DC rails in series and leaking to earth) [W]; 0 with an
            ideal return and for AC.
        rail_potential_v: rail-to-earth potentials of the rail nodes (DC), or empty.
        guess: this step's potentials, to start the next step from (DC), or None.
        storage_power_w: power taken by each wayside storage at its terminals (negative: given) [W].
        stray_current_a: current leaving the rails into the earth (trainsim.power.rail) [A]; NaN
            without rail-to-earth conductance or rail potentials.
    """

    converged: bool
    iterations: int
    train_voltage_v: np.ndarray
    train_power_w: np.ndarray
    train_current_a: np.ndarray
    traction_share: np.ndarray
    regen_share: np.ndarray
    substation_power_w: np.ndarray
    substation_source_w: np.ndarray
    substation_current_a: np.ndarray
    substation_on: np.ndarray
    line_loss_w: float
    substation_loss_w: float
    contact_loss_w: float
    return_loss_w: float
    rail_potential_v: np.ndarray
    guess: StepGuess | None = None
    storage_power_w: np.ndarray | None = None
    stray_current_a: float = float("nan")


@dataclass
class StepGuess:
    """Potentials of a previous step to start Newton from [V] (DC).

    Attributes:
        fixed_v: potential of each fixed node of the topology (substations, connections, track
            ends), NaN where unknown.
        train_contact_v, train_rail_v: contact and rail potential of each train, in the order of
            the step's loads, NaN where unknown (a train that just entered).
    """

    fixed_v: np.ndarray
    train_contact_v: np.ndarray
    train_rail_v: np.ndarray


def _start_from_guess(asm: _Assembly, guess: StepGuess, contact_default: float) -> np.ndarray:
    v = np.zeros(asm.n)
    v[:] = np.nan
    ok = asm.fixed_index >= 0
    v[asm.fixed_index[ok]] = guess.fixed_v[ok]
    for nodes, values in ((asm.train_c, guess.train_contact_v), (asm.train_r, guess.train_rail_v)):
        m = nodes >= 0
        v[nodes[m]] = values[m]
    # nodes without a guess: contact nodes at the mean no-load voltage, rails at 0
    missing = np.isnan(v)
    if missing.any():
        v[missing] = contact_default
        rails = asm.rail_nodes[missing[asm.rail_nodes]]
        v[rails] = 0.0
    return v


@dataclass
class _Assembly:
    n: int  # nodes (earth excluded)
    a: np.ndarray  # branch ends (node ids, -1 earth)
    b: np.ndarray
    y: np.ndarray  # branch admittances [S]
    train_c: np.ndarray  # train contact / rail nodes
    train_r: np.ndarray
    rail_nodes: np.ndarray
    fixed_index: np.ndarray  # unknown index of each fixed node of the topology (-1 earthed)
    storage_c: np.ndarray | None = None  # wayside storages' contact / rail nodes
    storage_r: np.ndarray | None = None
    storage_limits: tuple | None = None  # (charge max, discharge max, charge above, discharge below, ramp)
    sources: _Sources | None = None  # the substations' source laws (regulation curves)
    leaky_segments: tuple | None = None  # rail segments with leakage: node a, node b, length, r, g
    #: each unknown's place when the unknowns are taken along the line (by chainage): the nodal
    #: matrix is then a narrow band (DC; None: natural order)
    band_place: np.ndarray | None = None


class _Sources:
    """The substations' current laws in terms of x = R_i I(U) [V], a voltage-like variable that is
    E - U for a Thevenin source and R_i times the inverse regulation curve otherwise; the diode
    rounding acts on x, so that a rectifier with a curve blocks exactly like one without."""

    def __init__(self, subs) -> None:
        self.reversible = np.array([s.reversible for s in subs], dtype=bool)
        self.curved = np.array([s.regulation is not None for s in subs], dtype=bool)
        self.curves = {
            k: (
                np.array([q[0] for q in s.regulation], dtype=float),
                np.array([q[1] for q in s.regulation], dtype=float),
                s.internal_resistance_ohm,
            )
            for k, s in enumerate(subs)
            if s.regulation is not None
        }

    def x(self, index: np.ndarray, e: np.ndarray, us: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x and dx/dU of the substations ``index`` (e, us: their no-load and busbar voltages)."""
        x = e - us
        dxdu = -np.ones(len(index))
        if not self.curves:
            return x, dxdu
        for j, k in enumerate(index.tolist()):
            curve = self.curves.get(int(k))
            if curve is not None:
                i, slope = regulation_current_a(float(us[j]), curve[0], curve[1])
                x[j] = curve[2] * i
                dxdu[j] = curve[2] * slope
        return x, dxdu


def assemble(net: Network, track: np.ndarray, position_m: np.ndarray) -> _Assembly:
    """Nodes and branches for trains at the given tracks and positions (all on the wire)."""
    if net.system == "ac":
        return _assemble_numpy(net, track, position_m)
    return _assemble_dc(net, track, position_m)


def _assemble_numpy(net: Network, track: np.ndarray, position_m: np.ndarray) -> _Assembly:
    """:func:`assemble` in numpy, AC and DC (DC goes through :func:`_assemble_dc`, tested equal)."""
    topo = net.topology
    ac = net.system == "ac"
    ideal = net.ideal_return
    next_id = topo.n_fixed
    a_parts, b_parts, y_parts = [], [], []
    train_c = np.empty(len(track), dtype=np.int64)
    train_r = np.empty(len(track), dtype=np.int64)
    rail_nodes = []
    leaky: list[tuple[np.ndarray, ...]] = []
    for ti, t in enumerate(net.tracks):
        sel = np.flatnonzero(track == ti)
        fp = topo.fixed_positions[ti]
        xt = np.round(position_m[sel] / POSITION_RESOLUTION_M) * POSITION_RESOLUTION_M
        nf = len(fp)
        uniq, inv = np.unique(np.concatenate([fp, xt]), return_inverse=True)
        cu = np.empty(len(uniq), dtype=np.int64)
        ru = np.empty(len(uniq), dtype=np.int64)
        is_new = np.ones(len(uniq), dtype=bool)
        is_new[inv[:nf]] = False
        cu[inv[:nf]] = topo.contact_ids[ti]
        ru[inv[:nf]] = topo.rail_ids[ti]
        k = int(is_new.sum())
        cu[is_new] = next_id + np.arange(k)
        next_id += k
        if ideal:
            ru[is_new] = -1
        else:
            ru[is_new] = next_id + np.arange(k)
            next_id += k
            rail_nodes.append(ru)
        train_c[sel] = cu[inv[nf:]]
        train_r[sel] = ru[inv[nf:]]
        dx = np.diff(uniq)
        keep = ~topo.segment_cut(ti, uniq[:-1], uniq[1:])
        z = (
            complex(t.contact_resistance_ohm_per_m, t.contact_reactance_ohm_per_m)
            if ac
            else t.contact_resistance_ohm_per_m
        )
        a_parts.append(cu[:-1][keep])
        b_parts.append(cu[1:][keep])
        y_parts.append(1.0 / (z * dx[keep]))
        # leakage contact -> return at every node (keeps isolated sections solvable; losses counted)
        a_parts.append(cu)
        b_parts.append(ru)
        y_parts.append(np.full(len(uniq), net.contact_leakage_s))
        if not ideal:
            # the rails between nodes: the exact pi-equivalent of a uniformly leaking line
            r, g = t.rail_resistance_ohm_per_m, t.rail_to_earth_conductance_s_per_m
            y_series, y_shunt = leaky_rail_pi(r, g, dx)
            a_parts.append(ru[:-1])
            b_parts.append(ru[1:])
            y_parts.append(y_series)
            if g > 0:
                shunt = np.zeros(len(uniq))
                shunt[:-1] += y_shunt
                shunt[1:] += y_shunt
                a_parts.append(ru)
                b_parts.append(np.full(len(uniq), -1, dtype=np.int64))
                y_parts.append(shunt)
                leaky.append((ru[:-1], ru[1:], dx, np.full(len(dx), r), np.full(len(dx), g)))
    a = np.concatenate(a_parts)
    b = np.concatenate(b_parts)
    y = np.concatenate(y_parts)
    rail = np.concatenate(rail_nodes) if rail_nodes else np.empty(0, dtype=np.int64)
    leaky_parts = tuple(np.concatenate(parts) for parts in zip(*leaky, strict=True)) if leaky else None
    return _renumbered(topo, a, b, y, train_c, train_r, rail, leaky_parts, next_id)


def _dc_track_data(net: Network) -> tuple:
    """The per-track arrays :func:`_assemble_dc_kernel` reads, built once per network."""
    topo = net.topology
    cached = getattr(topo, "_assembly_track_data", None)
    if cached is not None:
        return cached
    fp = topo.fixed_positions
    out = (
        np.int64(topo.n_fixed),
        np.concatenate(fp).astype(float),
        np.cumsum([0, *(len(f) for f in fp)]).astype(np.int64),
        np.concatenate(topo.contact_ids).astype(np.int64),
        np.concatenate(topo.rail_ids).astype(np.int64),
        np.concatenate([np.asarray(g, dtype=float) for g in topo.gap_starts] or [np.empty(0)]),
        np.concatenate([np.asarray(g, dtype=float) for g in topo.gap_ends] or [np.empty(0)]),
        np.cumsum([0, *(len(g) for g in topo.gap_starts)]).astype(np.int64),
        np.array([t.contact_resistance_ohm_per_m for t in net.tracks], dtype=float),
        np.array([t.rail_resistance_ohm_per_m for t in net.tracks], dtype=float),
        np.array([t.rail_to_earth_conductance_s_per_m for t in net.tracks], dtype=float),
        float(net.contact_leakage_s),
        bool(net.ideal_return),
    )
    topo._assembly_track_data = out
    return out


def _assemble_dc(net: Network, track: np.ndarray, position_m: np.ndarray) -> _Assembly:
    """:func:`assemble` of a DC network through the compiled kernel (the same nodes and branches)."""
    n_fixed, fp, fp_start, cid, rid, gs, ge, g_start, rc, rr, gr, leak, ideal = _dc_track_data(net)
    xt = np.round(np.asarray(position_m, dtype=float) / POSITION_RESOLUTION_M) * POSITION_RESOLUTION_M
    a, b, y, train_c, train_r, rail, la, lb, ll, lr, lg, next_id, node_pos = _assemble_dc_kernel(
        n_fixed, np.asarray(track, dtype=np.int64), xt, fp, fp_start, cid, rid, gs, ge, g_start, rc, rr, gr,
        leak, ideal, _RAIL_SMALL,
    )  # fmt: skip
    leaky = (la, lb, ll, lr, lg) if len(la) else None
    return _renumbered(net.topology, a, b, y, train_c, train_r, rail, leaky, int(next_id), node_pos)


def _renumbered(topo, a, b, y, train_c, train_r, rail, leaky, next_id: int, node_pos=None) -> _Assembly:
    """The assembly with earthed nodes as the reference (-1) and the unknowns numbered 0..n-1."""
    # earthed nodes are the reference
    if topo.earthed:
        earthed = np.fromiter(topo.earthed, dtype=np.int64)
        a = np.where(np.isin(a, earthed), -1, a)
        b = np.where(np.isin(b, earthed), -1, b)
        train_r = np.where(np.isin(train_r, earthed), -1, train_r)
    # renumber so that the unknowns are 0..n-1 (earthed fixed nodes dropped)
    used = np.ones(next_id, dtype=bool)
    if topo.earthed:
        used[list(topo.earthed)] = False
    new_index = np.full(next_id + 1, -1, dtype=np.int64)  # last slot maps -1 -> -1
    new_index[:next_id][used] = np.arange(int(used.sum()))
    if leaky is not None:
        la, lb, ll, lr, lg = leaky
        leaky_segments = (new_index[la], new_index[lb], ll, lr, lg)
    else:
        leaky_segments = None
    band_place = None
    if node_pos is not None:
        order = np.argsort(node_pos[used], kind="stable")
        band_place = np.empty(len(order), dtype=np.int64)
        band_place[order] = np.arange(len(order))
    return _Assembly(
        band_place=band_place,
        leaky_segments=leaky_segments,
        n=int(used.sum()),
        a=new_index[a],
        b=new_index[b],
        y=y,
        train_c=new_index[train_c],
        train_r=new_index[train_r],
        rail_nodes=np.unique(new_index[rail][new_index[rail] >= 0]),
        fixed_index=new_index[: topo.n_fixed],
    )


def _stamp(a: np.ndarray, b: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """COO entries of two-terminal admittances y between nodes a and b (-1 = earth)."""
    ma, mb = a >= 0, b >= 0
    both = ma & mb
    rows = np.concatenate([a[ma], b[mb], a[both], b[both]])
    cols = np.concatenate([a[ma], b[mb], b[both], a[both]])
    vals = np.concatenate([y[ma], y[mb], -y[both], -y[both]])
    return rows, cols, vals


def _with_earth(v: np.ndarray) -> np.ndarray:
    """``v`` with the earth's potential 0 appended: indexing it with a node id of -1 (earth) gives 0,
    so ``_with_earth(v)[nodes]`` is ``_potential(v, nodes)`` without masks."""
    out = np.empty(len(v) + 1, dtype=v.dtype)
    out[:-1] = v
    out[-1] = 0
    return out


def _bins(nodes: np.ndarray, n: int) -> np.ndarray:
    """Node ids with earth (-1) sent to a spare bin n, for :func:`_injection_into`."""
    return np.where(nodes < 0, n, nodes)


def _injection_into(n: int, bins: np.ndarray, values: np.ndarray) -> np.ndarray:
    """:func:`_injection` (real) for node ids already mapped by :func:`_bins`: what goes to earth is
    summed in the spare bin and dropped; every other bin sums the same values in the same order."""
    return np.bincount(bins, weights=values, minlength=n + 1)[:n]


def _diode_forward(x: np.ndarray, delta: float) -> np.ndarray:
    """A diode rectifier's current over its conductance [V], max(x, 0) rounded over delta with a
    finite tail (DIODE_SMOOTHING_SHARE): 0 for x <= -delta, (x + delta)^2 / (4 delta) for |x| < delta,
    x for x >= delta (value and slope continuous at +-delta). A blocked rectifier (its busbar more
    than delta above E) then gives exactly 0 A, as the physical diode does."""
    x = np.asarray(x, dtype=float)
    inner = (x + delta) ** 2 / (4.0 * delta)
    return np.where(x >= delta, x, np.where(x <= -delta, 0.0, inner))


def _diode_forward_slope(x: np.ndarray, delta: float) -> np.ndarray:
    """Derivative of :func:`_diode_forward` with respect to x: 0, (x + delta) / (2 delta), 1."""
    x = np.asarray(x, dtype=float)
    return np.where(x >= delta, 1.0, np.where(x <= -delta, 0.0, (x + delta) / (2.0 * delta)))


#: Above this many unknowns the compiled Newton gives way to the sparse one: it keeps the band of its
#: Jacobian in full n x n storage (copied every iteration), cheap next to SuperLU's per-call ordering
#: and bookkeeping at a metro line's hundred nodes (the 20 km benchmark line: 86 nodes, half-bandwidth
#: about 6) and still at a few hundred.
DENSE_NEWTON_MAX_NODES = 400


def _potential(v: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    out = np.zeros(len(nodes), dtype=v.dtype)
    ok = nodes >= 0
    out[ok] = v[nodes[ok]]
    return out


def _injection(n: int, nodes: np.ndarray, values: np.ndarray, dtype) -> np.ndarray:
    """Sum of ``values`` per node (entries at earth, -1, dropped)."""
    ok = nodes >= 0
    if np.dtype(dtype).kind == "c":
        vals = np.asarray(values, dtype=complex)[ok]
        return np.bincount(nodes[ok], weights=vals.real, minlength=n) + 1j * np.bincount(
            nodes[ok], weights=vals.imag, minlength=n
        )
    return np.bincount(nodes[ok], weights=np.asarray(values, dtype=float)[ok], minlength=n)


class _Pattern:
    """A fixed sparsity pattern in CSC order, assembled from two-terminal stamps: the matrix is
    built once and only its values change between Newton iterations (no sparse-format
    conversions inside the loop)."""

    def __init__(self, n: int, pairs: list[tuple[np.ndarray, np.ndarray]]) -> None:
        self.n = n
        lengths = [len(a) for a, _ in pairs]
        starts = np.cumsum([0, *lengths]).astype(np.int64)
        a_all = np.concatenate([np.asarray(a, dtype=np.int64) for a, _ in pairs])
        b_all = np.concatenate([np.asarray(b, dtype=np.int64) for _, b in pairs])
        rows, cols, take, sign, bounds, uniq, inv = _stamp_pattern(a_all, b_all, starts, n)
        self.parts = [
            (rows[lo:hi], cols[lo:hi], take[lo:hi], sign[lo:hi]) for lo, hi in pairwise(bounds.tolist())
        ]
        self.nnz = len(uniq)
        self.slots = [inv[lo:hi] for lo, hi in pairwise(bounds.tolist())]
        indptr = np.concatenate([[0], np.cumsum(np.bincount(uniq // n, minlength=n))])
        self.matrix = sp.csc_matrix(
            (np.zeros(self.nnz), (uniq % n).astype(np.int32), indptr.astype(np.int32)), shape=(n, n)
        )

    def values(self, k: int, y: np.ndarray) -> np.ndarray:
        """The CSC data contributed by part k with element admittances y."""
        _, _, take, sign = self.parts[k]
        return np.bincount(self.slots[k], weights=y[take] * sign, minlength=self.nnz)

    def matvec(self, k: int, y: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(Part k's matrix) @ v, without building it."""
        rows, cols, take, sign = self.parts[k]
        return np.bincount(rows, weights=y[take] * sign * v[cols], minlength=self.n)

    def weights(self, k: int, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rows, cols, signed element weights) of part k with admittances y: ``matvec`` is the
        bincount of ``weights * v[cols]`` over ``rows``."""
        rows, cols, take, sign = self.parts[k]
        return rows, cols, y[take] * sign


@dataclass(frozen=True)
class _Constants:
    """What every step of a network needs and only the network decides (built once per network)."""

    sub_p: np.ndarray  # substations' positive / negative unknowns (-1 earth)
    sub_n: np.ndarray
    e: np.ndarray  # no-load voltages [V]
    ys: np.ndarray  # internal admittances [S]
    sources: _Sources
    linear: np.ndarray  # reversible Thevenin sources: linear, in the matrix
    storage_c: np.ndarray | None  # wayside storages' contact / rail unknowns
    storage_r: np.ndarray | None
    storage_thresholds: tuple  # charge above, discharge below, ramp [V]


def _constants(net: Network) -> _Constants:
    """The network's :class:`_Constants`, kept on its topology (the network is immutable)."""
    topo = net.topology
    cached = getattr(topo, "_solver_constants", None)
    if cached is not None:
        return cached
    subs = net.substations
    sub_p = np.array([topo.substation_nodes[i][0] for i in range(len(subs))], dtype=np.int64)
    sub_n = np.array([topo.substation_nodes[i][1] for i in range(len(subs))], dtype=np.int64)
    if topo.earthed:
        earthed = np.fromiter(topo.earthed, dtype=np.int64)
        sub_n = np.where(np.isin(sub_n, earthed), -1, sub_n)
    # fixed node ids keep their order below n_fixed except for dropped earthed ones: remap
    remap = np.full(topo.n_fixed + 1, -1, dtype=np.int64)
    used = np.ones(topo.n_fixed, dtype=bool)
    if topo.earthed:
        used[list(topo.earthed)] = False
    remap[:-1][used] = np.arange(int(used.sum()))
    sub_p, sub_n = remap[sub_p], remap[sub_n]
    storage_c = storage_r = None
    if net.storages:
        st_c = np.array([c for c, _ in topo.storage_nodes], dtype=np.int64)
        st_r = np.array([r for _, r in topo.storage_nodes], dtype=np.int64)
        if topo.earthed:
            st_r = np.where(np.isin(st_r, np.fromiter(topo.earthed, dtype=np.int64)), -1, st_r)
        storage_c, storage_r = remap[st_c], remap[st_r]
    e = np.array([s.no_load_voltage_v for s in subs])
    z = np.array([complex(s.internal_resistance_ohm, s.internal_reactance_ohm) for s in subs])
    ys = 1.0 / z if net.system == "ac" else 1.0 / z.real
    sources = _Sources(subs)
    out = _Constants(
        sub_p=sub_p,
        sub_n=sub_n,
        e=e,
        ys=ys,
        sources=sources,
        linear=sources.reversible & ~sources.curved,
        storage_c=storage_c,
        storage_r=storage_r,
        storage_thresholds=(
            np.array([st.charge_above_v for st in net.storages]),
            np.array([st.discharge_below_v for st in net.storages]),
            np.array([st.ramp_v for st in net.storages]),
        ),
    )
    for a in (sub_p, sub_n, e, ys, out.linear, sources.reversible, sources.curved):
        a.flags.writeable = False  # shared by every step: a step that wrote into one would corrupt the next
    topo._solver_constants = out
    return out


def solve_step(
    net: Network, loads: StepLoads, substation_on: np.ndarray | None = None, guess: StepGuess | None = None
) -> StepSolution:
    """Solve one instant: node potentials, trains' accepted powers, substation powers.

    ``substation_on`` is informative only (kept for callers; rectifier states are solved from
    scratch every step). ``guess`` (DC) starts Newton from a previous step's potentials (fixed
    nodes, and each train's contact and rail potentials in the order of ``loads``); without it, or
    if Newton fails from it, the flat start and the fallbacks below are used.
    """
    _check_loads(net, loads)
    asm = assemble(net, loads.track, loads.position_m)
    topo = net.topology
    lim = net.limits
    ac = net.system == "ac"
    subs = net.substations
    k = _constants(net)
    sub_p, sub_n, e, ys = k.sub_p, k.sub_n, k.e, k.ys
    n_st = len(net.storages)
    if n_st:
        asm.storage_c, asm.storage_r = k.storage_c, k.storage_r
        cmax = np.zeros(n_st) if loads.storage_charge_max_w is None else loads.storage_charge_max_w
        dmax = np.zeros(n_st) if loads.storage_discharge_max_w is None else loads.storage_discharge_max_w
        asm.storage_limits = (cmax, dmax, *k.storage_thresholds)
    asm.sources = k.sources
    reversible = asm.sources.reversible
    linear = k.linear
    un = lim.nominal_v
    tol = VOLTAGE_TOLERANCE_SHARE * un
    if ac:
        v, iterations, converged, on_ac = _active_set_ac(
            net, asm, loads, sub_p, sub_n, e, ys, tol, reversible
        )
    else:
        iterations = 0
        converged = False
        if guess is not None:
            v0 = _start_from_guess(asm, guess, float(np.mean(e)))
            v, iterations, converged = _newton_dc(
                net, asm, loads, sub_p, sub_n, e, ys, linear.copy(), tol, v0
            )
        if not converged:
            v, its, converged = _newton_dc(net, asm, loads, sub_p, sub_n, e, ys, linear.copy(), tol, None)
            iterations += its
        if not converged and not reversible.all():
            # Newton from the no-load voltage may stall before a hump of the residual: when every
            # rectifier of a section blocks and the regenerated power exceeds what the other trains
            # and the losses take, the voltage must rise until regeneration is curtailed, while the
            # residual first grows (constant-power loads draw less current as the voltage rises).
            # Continuation: the rectifiers are first given a reverse conductance equal to their
            # forward one (a reversible network, well conditioned), which is then divided by 10 at
            # each stage down to 1e-9 of it, each stage starting from the previous solution; the
            # last stage is the true rectifier.
            # First try the branch where regeneration is curtailed (the usual cause): start every
            # contact node in the middle of the curtailment ramp and keep regenerating trains on it.
            if n_st and np.any(loads.regen_w > 0):
                # a wayside storage may be the one sink left: start in the middle of its charging ramp
                for k, st in enumerate(net.storages):
                    if converged or asm.storage_limits[0][k] <= 0:
                        continue
                    v, its, converged = _newton_dc(
                        net,
                        asm,
                        loads,
                        sub_p,
                        sub_n,
                        e,
                        ys,
                        linear.copy(),
                        tol,
                        None,
                        start_v=st.charge_above_v + 0.5 * st.ramp_v,
                    )
                    iterations += its
            start = 0.5 * (lim.regen_full_v + lim.regen_zero_v)
            if not converged and np.any(loads.regen_w > 0):
                v, its, converged = _newton_dc(
                    net,
                    asm,
                    loads,
                    sub_p,
                    sub_n,
                    e,
                    ys,
                    linear.copy(),
                    tol,
                    None,
                    start_v=start,
                    keep_curtailed=True,
                )
                iterations += its
        if not converged and np.any(loads.traction_w > 0):
            # a train asking more than the line can give at full traction: the solution lies on the
            # EN 50388 ramp, which Newton from the no-load voltage may not reach (the constant-power
            # branch above it has no solution); start on the ramp
            start = 0.5 * (lim.min1_v + lim.traction_full_v)
            v, its, converged = _newton_dc(
                net, asm, loads, sub_p, sub_n, e, ys, linear.copy(), tol, None, start_v=start
            )
            iterations += its
        if not converged and not reversible.all():
            v = None
            for reverse_share in (*(10.0**-k for k in range(10)), 0.0):
                v, its, converged = _newton_dc(
                    net,
                    asm,
                    loads,
                    sub_p,
                    sub_n,
                    e,
                    ys,
                    linear.copy(),
                    tol,
                    v,
                    reverse_share=reverse_share,
                )
                iterations += its
                if not converged:
                    break
    ve = _with_earth(v)
    # results
    uc = ve[asm.train_c] - ve[asm.train_r]
    umag = np.abs(uc)
    a_share = traction_availability(umag, lim.min1_v, lim.traction_full_v)
    r_share = regen_acceptance(umag, lim.regen_full_v, lim.regen_zero_v)
    p_train = loads.traction_w * a_share + loads.auxiliary_w - loads.regen_w * r_share
    us = ve[sub_p] - ve[sub_n]
    if ac:
        on = on_ac
        i_sub = (e - us) * ys * on
    else:
        delta = DIODE_SMOOTHING_SHARE * un
        x_all, _ = asm.sources.x(np.arange(len(subs)), e, us.real)
        i_sub = np.where(reversible, x_all * ys, _diode_forward(x_all, delta) * ys)
        on = reversible | (x_all > 0)
    if ac:
        s_bus = us * np.conj(i_sub)
        p_bus = s_bus.real
        p_src = (e * np.conj(i_sub)).real
        i_sub_signed = np.abs(i_sub) * np.sign(p_bus)
        i_train = np.abs(p_train * (1 + 1j * loads.tan_phi) / np.where(umag > 0, umag, 1.0)) * np.sign(
            p_train
        )
    else:
        p_bus = us * i_sub.real
        p_src = e * i_sub.real
        i_sub_signed = i_sub.real
        i_train = p_train / np.maximum(umag, 1e-3 * un)
    dv = ve[asm.a] - ve[asm.b]
    branch_loss = np.abs(dv) ** 2 * np.real(asm.y)
    # a branch with no contact node at either end is of the return: rails in series, rails to earth
    # (the earth, the last entry, counts with the return); the contact-to-return leakage is the contact line's
    return_side = np.zeros(asm.n + 1, dtype=bool)
    return_side[asm.rail_nodes] = True
    return_side[-1] = True
    of_return = return_side[asm.a] & return_side[asm.b]
    return_loss = float(np.sum(branch_loss[of_return]))
    contact_loss = float(np.sum(branch_loss[~of_return]))
    line_loss = contact_loss + return_loss
    sub_loss = float(np.sum(p_src - p_bus))
    rail = (
        np.real(v[asm.rail_nodes]) if (not net.ideal_return and topo.rail_potential_defined) else np.empty(0)
    )
    stray = float("nan")
    if len(rail) and asm.leaky_segments is not None:
        la, lb, ll, lr, lg = asm.leaky_segments
        stray = float(segment_leakage_total_a(np.real(ve[la]), np.real(ve[lb]), ll, lr, lg))
    p_storage = None
    if n_st:
        u_st = ve[asm.storage_c] - ve[asm.storage_r]
        p_storage, _ = storage_power_w(np.real(u_st), *asm.storage_limits)
    guess_out = None
    if not ac:
        fixed_v = np.where(asm.fixed_index >= 0, v[np.maximum(asm.fixed_index, 0)], 0.0)
        guess_out = StepGuess(fixed_v, ve[asm.train_c], ve[asm.train_r])
    return StepSolution(
        guess=guess_out,
        storage_power_w=p_storage,
        converged=converged,
        iterations=iterations,
        train_voltage_v=umag,
        train_power_w=p_train,
        train_current_a=np.real(i_train),
        traction_share=a_share,
        regen_share=r_share,
        substation_power_w=p_bus,
        substation_source_w=p_src,
        substation_current_a=np.real(i_sub_signed),
        substation_on=on,
        line_loss_w=line_loss,
        substation_loss_w=sub_loss,
        contact_loss_w=contact_loss,
        return_loss_w=return_loss,
        rail_potential_v=rail,
        stray_current_a=stray,
    )


#: A train may stand this far beyond its track's end and still be at the end [m] (round-off of
#: chainage arithmetic; far below the node resolution POSITION_RESOLUTION_M).
TRACK_END_TOLERANCE_M = 1e-6


def _check_loads(net: Network, loads: StepLoads) -> None:
    """An InputError naming the train (its place in ``loads``), its value and what is allowed, for a
    train whose track is unknown, whose position is not finite or off its track's extent, or that
    stands inside a neutral section (no supply: leave it out of the step's loads), or whose powers
    are not finite and >= 0. Positions off the track used to be extrapolated silently."""
    track = np.asarray(loads.track)
    x = np.asarray(loads.position_m, dtype=float)
    n = len(track)

    def name_of(k: int) -> str:
        ids = loads.train_ids
        return f"train {ids[k]}" if ids is not None and k < len(ids) else f"train {k} of the step"

    arrays = {"position_m": x, "traction_w": loads.traction_w, "regen_w": loads.regen_w,
              "auxiliary_w": loads.auxiliary_w, "tan_phi": loads.tan_phi}  # fmt: skip
    for name, a in arrays.items():
        if np.shape(a) != (n,):
            raise InputError("the step's load arrays must have one entry per train", field=f"loads.{name}",
                             value=f"shape {np.shape(a)}", allowed=f"shape ({n},), as loads.track")  # fmt: skip
    n_tracks = len(net.tracks)
    bad = np.flatnonzero((track < 0) | (track >= n_tracks) | (track != np.round(track)))
    if len(bad):
        k = int(bad[0])
        raise InputError(f"{name_of(k)} is on an unknown track", field=f"loads.track[{k}]",
                         value=track[k].item(), allowed=f"a track index 0 .. {n_tracks - 1}")  # fmt: skip
    track = track.astype(np.int64)
    extents = net.topology.extents_m
    start, end = extents[0][track], extents[1][track]
    off = ~(np.isfinite(x) & (x >= start - TRACK_END_TOLERANCE_M) & (x <= end + TRACK_END_TOLERANCE_M))
    if off.any():
        k = int(np.flatnonzero(off)[0])
        t = net.tracks[track[k]]
        raise InputError(
            f"{name_of(k)} is off its track {t.id}",
            field=f"loads.position_m[{k}]",
            value=float(x[k]),
            allowed=f"track {t.id}'s extent {t.start_m:.3f} .. {t.end_m:.3f} m",
        )
    for g in net.gaps:
        if g.end_m <= g.start_m:
            continue  # a section insulator: a train on it is on one side or the other
        inside = np.flatnonzero((track == net.track_index(g.track)) & (x > g.start_m) & (x < g.end_m))
        if len(inside):
            k = int(inside[0])
            raise InputError(
                f"{name_of(k)} stands inside neutral section {g.id} of track {g.track}: it has no supply there",
                field=f"loads.position_m[{k}]",
                value=float(x[k]),
                allowed=f"outside {g.start_m:.3f} .. {g.end_m:.3f} m (leave the train out of the step's loads)",
            )
    for name in ("traction_w", "regen_w", "auxiliary_w"):
        a = np.asarray(arrays[name], dtype=float)
        wrong = ~(np.isfinite(a) & (a >= 0))
        if wrong.any():
            k = int(np.flatnonzero(wrong)[0])
            raise InputError(f"{name_of(k)} has an invalid power", field=f"loads.{name}[{k}]",
                             value=float(a[k]), allowed="a finite power >= 0 W")  # fmt: skip


def _base_matrix(asm: _Assembly, sub_p, sub_n, ys, on, dtype):
    rows, cols, vals = _stamp(asm.a, asm.b, asm.y.astype(dtype))
    sr, sc, sv = _stamp(sub_p[on], sub_n[on], np.asarray(ys, dtype=dtype)[on])
    return np.concatenate([rows, sr]), np.concatenate([cols, sc]), np.concatenate([vals, sv])


def _newton_dc(
    net,
    asm: _Assembly,
    loads: StepLoads,
    sub_p,
    sub_n,
    e,
    ys,
    on,
    tol,
    v0,
    start_v: float | None = None,
    reverse_share: float = 0.0,
    keep_curtailed: bool = False,
    max_iterations: int = MAX_NEWTON_ITERATIONS,
):
    """Newton's method on the DC nodal equations; returns (V, iterations, converged)."""
    lim = net.limits
    un = lim.nominal_v
    n = asm.n
    # reversible substations are linear (in the matrix); diode rectifiers (``on`` False here) are
    # nonlinear elements I_s = max(E - U_s, 0) / R_i inside the residual (semismooth Newton), so
    # that I_s >= 0 and I_s (U_s - E) = 0 hold by construction
    ys = np.asarray(ys, dtype=float)
    dio = ~on
    st_c = asm.storage_c if asm.storage_c is not None else np.empty(0, dtype=np.int64)
    st_r = asm.storage_r if asm.storage_r is not None else np.empty(0, dtype=np.int64)
    ys_on = ys[on]
    delta = DIODE_SMOOTHING_SHARE * un
    dp_, dn_, de, dy = sub_p[dio], sub_n[dio], e[dio], ys[dio]
    d_index = np.flatnonzero(dio)
    d_exact = asm.sources.reversible[dio]  # reversible with a regulation curve: no diode
    if v0 is None:
        # flat start: contact nodes at the mean no-load voltage, rails at 0
        v = np.zeros(n)
        cnodes = np.unique(np.concatenate([asm.a[asm.y == net.contact_leakage_s], sub_p]))
        v[cnodes[cnodes >= 0]] = float(np.mean(e)) if start_v is None else start_v
        rnodes = asm.rail_nodes
        v[rnodes] = 0.0
    else:
        v = v0.copy()
    tc, tr = asm.train_c, asm.train_r
    u_floor = 1e-3 * un
    ftol = CURRENT_TOLERANCE_SHARE * max(float(np.sum(np.abs(e * ys))), 1.0)
    if len(st_c) == 0 and not asm.sources.curves and 0 < n <= DENSE_NEWTON_MAX_NODES:
        place = asm.band_place if asm.band_place is not None else np.arange(n)
        v_out, its, converged, singular = _newton_dc_dense(
            v, place, asm.a, asm.b, np.asarray(asm.y, dtype=float), sub_p[on], sub_n[on], ys_on, e[on],
            dp_, dn_, de, dy, tc, tr, np.asarray(loads.traction_w, dtype=float),
            np.asarray(loads.auxiliary_w, dtype=float), np.asarray(loads.regen_w, dtype=float),
            float(u_floor), float(lim.min1_v), float(lim.traction_full_v), float(lim.regen_full_v),
            float(lim.regen_zero_v), float(delta), float(reverse_share), bool(keep_curtailed),
            int(max_iterations), float(tol), float(ftol), float(MAX_STEP_SHARE * un),
        )  # fmt: skip
        if not singular:
            return v_out, its, converged
        # a singular Jacobian: the sparse path below reports it as it always has
    pattern = _Pattern(
        n,
        [
            (asm.a, asm.b),
            (sub_p[on], sub_n[on]),
            (asm.train_c, asm.train_r),
            (sub_p[dio], sub_n[dio]),
            (st_c, st_r),
        ],
    )
    g_data = pattern.values(0, asm.y) + pattern.values(1, ys[on])
    j_src = _injection(n, sub_p[on], (e * ys)[on], float) - _injection(n, sub_n[on], (e * ys)[on], float)
    # the residual is evaluated a few times per Newton iteration: what does not depend on v is
    # formed once (the same operations in the same order as before, so the same figures bit for bit)
    tc_bins, tr_bins = _bins(tc, n), _bins(tr, n)
    dp_bins, dn_bins = _bins(dp_, n), _bins(dn_, n)
    st_c_bins, st_r_bins = _bins(st_c, n), _bins(st_r, n)

    kernel_args = (
        tc, tr, tc_bins, tr_bins, *pattern.weights(0, asm.y), *pattern.weights(1, ys_on), j_src,
        np.asarray(loads.traction_w, dtype=float), np.asarray(loads.auxiliary_w, dtype=float),
        np.asarray(loads.regen_w, dtype=float), float(u_floor), float(lim.min1_v), float(lim.traction_full_v),
        float(lim.regen_full_v), float(lim.regen_zero_v),
    )  # fmt: skip

    def residual(v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        f, uu, p = _dc_load_residual(v, *kernel_args)
        if len(de) or len(st_c):
            ve = _with_earth(v)
        if len(de):
            x, _ = asm.sources.x(d_index, de, ve[dp_] - ve[dn_])
            forward = np.where(d_exact, x, _diode_forward(x, delta))
            i_d = (forward + reverse_share * (x - forward)) * dy
            f += _injection_into(n, dn_bins, i_d) - _injection_into(n, dp_bins, i_d)
        if len(st_c):
            us = np.maximum(ve[st_c] - ve[st_r], u_floor)
            ps, _ = storage_power_w(us, *asm.storage_limits)
            i_s = ps / us
            f += _injection_into(n, st_c_bins, i_s) - _injection_into(n, st_r_bins, i_s)
        return f, uu, p

    f, uu, p = residual(v)
    norm = float(np.max(np.abs(f))) if n else 0.0
    stalls = 0
    for it in range(1, max_iterations + 1):
        if norm < ftol:
            return v, it - 1, True
        dp = loads.traction_w * traction_availability_slope(uu, lim.min1_v, lim.traction_full_v) - (
            loads.regen_w * regen_acceptance_slope(uu, lim.regen_full_v, lim.regen_zero_v)
        )
        di = np.where(uu > u_floor, dp / uu - p / uu**2, 0.0)
        data = g_data + pattern.values(2, di)
        ve = _with_earth(v)
        if len(de):
            x, dxdu = asm.sources.x(d_index, de, ve[dp_] - ve[dn_])
            slope = np.where(d_exact, 1.0, _diode_forward_slope(x, delta))
            data = data + pattern.values(3, -dxdu * dy * (slope + reverse_share * (1.0 - slope)))
        if len(st_c):
            us = np.maximum(ve[st_c] - ve[st_r], u_floor)
            ps, dps = storage_power_w(us, *asm.storage_limits)
            data = data + pattern.values(4, dps / us - ps / us**2)
        pattern.matrix.data[:] = data
        dv = -splu(pattern.matrix).solve(f)
        step = float(np.max(np.abs(dv)))
        if step > MAX_STEP_SHARE * un:
            dv *= MAX_STEP_SHARE * un / step
        # fraction to the boundary: a regenerating train's voltage never steps past the voltage where
        # its regeneration stops (above it only constant-power auxiliaries remain, whose negative
        # incremental conductance would send Newton the wrong way in a section with every rectifier
        # blocked)
        dve = _with_earth(dv)
        du = dve[tc] - dve[tr]
        rising = (loads.regen_w > 0) & (du > 0) & (uu < lim.regen_zero_v)
        if rising.any():
            room = np.min(0.9 * (lim.regen_zero_v - uu[rising]) / du[rising])
            if room < 1.0:
                dv *= room
                step *= room
                du *= room
        if keep_curtailed:
            falling = (loads.regen_w > 0) & (du < 0) & (uu > lim.regen_full_v)
            if falling.any():
                room = np.min(0.9 * (uu[falling] - lim.regen_full_v) / -du[falling])
                if room < 1.0:
                    dv *= room
                    step *= room
        # backtracking on the residual: Newton steps across the kinks of a(u) and r(u) may cycle
        # (Euclidean norm, sufficient decrease); if no step length decreases it, the full step is
        # taken once in a while (non-monotone), which leaves shallow local minima of the residual
        lam = 1.0
        l2 = float(np.linalg.norm(f))
        accepted = False
        for _ in range(12):
            v_try = v + lam * dv
            f_try, uu_try, p_try = residual(v_try)
            if float(np.linalg.norm(f_try)) <= (1.0 - 1e-4 * lam) * l2 or lam * step < tol:
                accepted = True
                break
            lam *= 0.5
        if not accepted:
            stalls += 1
            if stalls % 3 == 0:
                lam = 1.0
                v_try = v + dv
                f_try, uu_try, p_try = residual(v_try)
        norm_try = float(np.max(np.abs(f_try)))
        v, f, uu, p, norm = v_try, f_try, uu_try, p_try, norm_try
        if lam * step < tol and norm < max(ftol, 1e3 * ftol * lam):
            return v, it, True
    return v, max_iterations, norm < ftol


def storage_power_w(
    u: np.ndarray, charge_max_w, discharge_max_w, charge_above_v, discharge_below_v, ramp_v
) -> tuple[np.ndarray, np.ndarray]:
    """Power taken by a wayside storage at terminal voltage U [W] (negative: given) and its
    derivative [W/V]: C ramp((U - U_ch) / w) - D ramp((U_dis - U) / w), where ramp(x) is
    clip(x, 0, 1) with its corners rounded over STORAGE_ROUNDING (Newton would otherwise stall when
    the storage takes just a little, at the corner)."""
    x_c = (u - charge_above_v) / ramp_v
    x_d = (discharge_below_v - u) / ramp_v
    d = STORAGE_ROUNDING
    ramp_c = _smooth_max(x_c, d) - _smooth_max(x_c - 1.0, d)
    ramp_d = _smooth_max(x_d, d) - _smooth_max(x_d - 1.0, d)
    slope_c = _smooth_max_slope(x_c, d) - _smooth_max_slope(x_c - 1.0, d)
    slope_d = _smooth_max_slope(x_d, d) - _smooth_max_slope(x_d - 1.0, d)
    p = charge_max_w * ramp_c - discharge_max_w * ramp_d
    dp = (charge_max_w * slope_c + discharge_max_w * slope_d) / ramp_v
    return p, dp


def _smooth_max(x: np.ndarray, delta: float) -> np.ndarray:
    """max(x, 0) rounded over delta: (x + sqrt(x^2 + delta^2)) / 2 (> 0 everywhere)."""
    return 0.5 * (x + np.sqrt(x * x + delta * delta))


def _smooth_max_slope(x: np.ndarray, delta: float) -> np.ndarray:
    """Derivative of :func:`_smooth_max` with respect to x."""
    return 0.5 * (1.0 + x / np.sqrt(x * x + delta * delta))


def _active_set_ac(net, asm: _Assembly, loads: StepLoads, sub_p, sub_n, e, ys, tol, reversible):
    """AC with non-reversible substations: a substation whose active power at the busbar would be
    negative is opened, an open one that would deliver active power if closed is closed again,
    until no state changes (at most one pass per substation and two more). Returns (V, iterations,
    converged, closed)."""
    on = np.ones(len(e), dtype=bool)
    total = 0
    for _ in range(len(e) + 2):
        v, its, converged = _fixed_point_ac(net, asm, loads, sub_p, sub_n, e, ys, tol, None, on)
        total += its
        us = _potential(v, sub_p) - _potential(v, sub_n)
        # active power at the busbar as it is (closed) or would be (open, first instant)
        p_bus = (us * np.conj((e - us) * ys)).real
        new_on = reversible | np.where(on, p_bus >= 0.0, p_bus > 0.0)
        if (new_on == on).all():
            return v, total, converged, on
        on = new_on
    return v, total, False, on


def _fixed_point_ac(net, asm: _Assembly, loads: StepLoads, sub_p, sub_n, e, ys, tol, v0, on=None):
    """Fixed-point (current injection) iteration on the AC phasor equations with the substations
    ``on`` closed (default all)."""
    lim = net.limits
    n = asm.n
    on = np.ones(len(e), dtype=bool) if on is None else on
    rows, cols, vals = _base_matrix(asm, sub_p, sub_n, ys, on, complex)
    lu = splu(sp.csc_matrix((vals, (rows, cols)), shape=(n, n)))
    j_src = _injection(n, sub_p[on], (e * ys)[on], complex) - _injection(n, sub_n[on], (e * ys)[on], complex)
    v = lu.solve(j_src) if v0 is None else v0.copy()
    tc, tr = asm.train_c, asm.train_r
    for it in range(1, MAX_FIXED_POINT_ITERATIONS + 1):
        ve = _with_earth(v)
        u = ve[tc] - ve[tr]
        um = np.maximum(np.abs(u), 1e-3 * lim.nominal_v)
        a_s = traction_availability(um, lim.min1_v, lim.traction_full_v)
        r_s = regen_acceptance(um, lim.regen_full_v, lim.regen_zero_v)
        p = loads.traction_w * a_s + loads.auxiliary_w - loads.regen_w * r_s
        s = p * (1 + 1j * loads.tan_phi)
        i_t = np.conj(s / np.where(np.abs(u) > 0, u, um))
        v_new = lu.solve(j_src - _injection(n, tc, i_t, complex) + _injection(n, tr, i_t, complex))
        step = np.max(np.abs(v_new - v)) if n else 0.0
        v = v_new
        if step < tol:
            return v, it, True
    return v, MAX_FIXED_POINT_ITERATIONS, False
