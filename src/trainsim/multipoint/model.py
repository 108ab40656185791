"""The multi-point train: one mass per vehicle, couplers between them, traction and braking per vehicle.

Source 000 ("Multi-point control models") describes the model: every vehicle has its own position,
speed and forces (the Newton equation of the single-point model, eq. 1, written per vehicle), and the
couplers between vehicles act as springs. Here each coupling is a spring-damper with optional free
slack, different stiffness and damping in draft (tension) and buff (compression), and a stiffer
"solid" stage once the draft gears have used their travel.

Everything is derived from a single-point :class:`~trainsim.model.Train` plus
:class:`MultiPointSettings`, so that a multi-point run and a single-point run of the same train use
the same effort curves, braking and resistance:

* masses and lengths per vehicle from ``train.vehicles``; inertial masses scaled so that their sum is
  the train's ``rho x m``;
* running resistance split per vehicle (terms of one vehicle type to the vehicles of that type, whole-train
  terms by mass), so that the per-vehicle laws add up to the train's law exactly;
* traction: every locomotive (default: the ``powered`` vehicles) gets a share of the train's effort
  curve (default: equal shares) or its own curve;
* braking: the friction (service) brake per vehicle proportional to its mass, the electric
  (regenerative) brake at the locomotives, an optional propagation delay of the brake command.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from trainsim.errors import InputError
from trainsim.model.effort import EffortCurve
from trainsim.model.laws import Quadratic
from trainsim.model.train import Train, Vehicle

# ---------------------------------------------------------------------------------------------- defaults
#: Friction ratio mu of the default friction draft gears [-] (wedge-type gears: the force is the spring
#: force times 1 + mu while the gear is loaded, times 1 - mu while it unloads; Cole 2006, Wu et al.
#: 2016, see docs/MULTIPOINT.md). A full loading-unloading cycle then absorbs 2 mu / (1 + mu) of the
#: work of loading: the MT-2 gear's absorptivity of >= 80 % (TB/T 2915) gives mu = 2/3.
FREIGHT_FRICTION_RATIO = 2.0 / 3.0
#: Stiffness of one freight wagon connection in draft and in buff [N/m], the mean of the gears' loading
#: and unloading branches. Two friction draft gears in series (one at each wagon end), each of the MT-2
#: type (TB/T 2915, used with AAR type E/F couplers on Chinese 70-80 t heavy-haul wagons): impedance
#: <= 2.27 MN at 83 mm travel, i.e. 2.27e6 / 0.083 = 2.7e7 N/m per gear and 1.4e7 N/m for the
#: connection, the secant stiffness of the loading branch = (1 + mu) x this; Miner's TF-880 (AAR
#: M-901E) gives the same order: 2.5 MN at 74 mm rated travel. 1.4e7 / (1 + 2/3) = 8.4e6 N/m.
FREIGHT_LOADING_STIFFNESS_N_PER_M = 1.4e7
FREIGHT_STIFFNESS_N_PER_M = FREIGHT_LOADING_STIFFNESS_N_PER_M / (1.0 + FREIGHT_FRICTION_RATIO)
#: Travel of one connection before the gears go solid [m]: 2 x 83 mm (MT-2 stroke).
FREIGHT_TRAVEL_M = 0.166
#: Stiffness once the gears are solid (coupler body and underframe) [N/m]: ASSUMPTION, 10 x the loading
#: branch of the gears.
FREIGHT_SOLID_STIFFNESS_N_PER_M = 1.4e8
#: Viscous damping of one connection [N s/m]: none by default, the gears' friction takes the losses.
#: (Before the friction model, 3.7e5 N s/m stood in for them: a linear damper dissipating the MT-2's
#: 80 % of an impact's energy in one half-cycle, damping ratio 0.25 for two 80 t wagons on 1.4e7 N/m;
#: it left the slowest coupler mode of a long train almost undamped, zeta about 0.005.)
FREIGHT_DAMPING_N_S_PER_M = 0.0
#: Capacity of one freight connection in draft and in buff [N]: the MT-2 gear's rated impedance (the
#: force at the end of its 83 mm travel, TB/T 2915), the force the loading branch above is the secant
#: of. Forces beyond it mean the gears have gone solid and the coupler and underframe take the rest: a
#: run that passes it gets a warning (see docs/MULTIPOINT.md, "Coupler capacities").
FREIGHT_CAPACITY_N = 2.27e6
#: Relative speed of the draft gears' wedges over which their friction turns from the unloading to the
#: loading branch [m/s] (regularised dry friction, tanh(rate / this)): small against the speeds of
#: coupler impacts and oscillations (0.01-0.5 m/s), large enough for Newton's method at 0.05 s steps.
FRICTION_VELOCITY_MPS = 0.005
#: Width over which the kinks of the piecewise-linear spring law are rounded [m]; keeps the force
#: continuously differentiable so that the Newton iterations of the implicit integrator converge.
COUPLER_SMOOTHING_M = 1.0e-3


@dataclass(frozen=True)
class CouplerModel:
    """One coupling between two vehicles: draft gears, coupler and free slack.

    Extension delta [m] of a coupling is the change of the distance between the two vehicles from its
    nominal value (the sum of the vehicles' lengths over couplers); positive in draft (tension),
    negative in buff (compression). The force, positive in tension, is

    * 0 inside the free slack, ``|delta| <= slack_m / 2`` (slack centred on the nominal distance);
    * ``k_draft x (delta - slack/2)`` beyond it in draft, ``k_buff x (delta + slack/2)`` in buff,
      stiffening to ``solid_stiffness_n_per_m`` after ``draft_travel_m`` / ``buff_travel_m``;
    * plus ``c x d(delta)/dt`` with the draft or buff damping, only while the gear is engaged;

    every kink rounded over ``smoothing_m`` (quadratic blend).

    Attributes:
        draft_stiffness_n_per_m: stiffness in tension [N/m].
        buff_stiffness_n_per_m: stiffness in compression [N/m].
        draft_damping_n_s_per_m: viscous damping in tension [N s/m].
        buff_damping_n_s_per_m: viscous damping in compression [N s/m].
        slack_m: total free play of the coupling [m] (0: slackless, e.g. drawbars).
        draft_travel_m: travel beyond the slack before the gear goes solid in tension [m].
        buff_travel_m: idem in compression [m].
        solid_stiffness_n_per_m: stiffness beyond the travel [N/m].
        smoothing_m: rounding width of the kinks [m].
        draft_capacity_n: largest tension the coupling is rated for [N]; a run whose force passes it
            gets a warning naming the coupling, the force, the time and the place; None: not checked.
        buff_capacity_n: largest compression it is rated for, as a positive force [N]; None: not
            checked.
        friction_ratio: wedge friction of friction draft gears, mu [-]: the force is the spring force
            times (1 + mu) while the gear is loaded (its travel growing) and times (1 - mu) while it
            unloads, blended by tanh(rate / friction_velocity_mps); 0: no friction (viscous damping
            only). See docs/MULTIPOINT.md, "Draft-gear friction".
        friction_velocity_mps: regularisation speed of that friction [m/s].
    """

    draft_stiffness_n_per_m: float = FREIGHT_STIFFNESS_N_PER_M
    buff_stiffness_n_per_m: float = FREIGHT_STIFFNESS_N_PER_M
    draft_damping_n_s_per_m: float = FREIGHT_DAMPING_N_S_PER_M
    buff_damping_n_s_per_m: float = FREIGHT_DAMPING_N_S_PER_M
    slack_m: float = 0.0
    draft_travel_m: float = FREIGHT_TRAVEL_M
    buff_travel_m: float = FREIGHT_TRAVEL_M
    solid_stiffness_n_per_m: float = FREIGHT_SOLID_STIFFNESS_N_PER_M
    smoothing_m: float = COUPLER_SMOOTHING_M
    draft_capacity_n: float | None = FREIGHT_CAPACITY_N
    buff_capacity_n: float | None = FREIGHT_CAPACITY_N
    friction_ratio: float = FREIGHT_FRICTION_RATIO
    friction_velocity_mps: float = FRICTION_VELOCITY_MPS

    def __post_init__(self) -> None:
        if not (math.isfinite(self.friction_ratio) and 0.0 <= self.friction_ratio < 1.0):
            raise InputError(
                "the draft gears' friction ratio must be >= 0 and below 1",
                field="couplers.friction_ratio",
                value=self.friction_ratio,
                allowed="0 <= friction_ratio < 1 (0: no friction)",
            )
        if not (math.isfinite(self.friction_velocity_mps) and 1e-5 <= self.friction_velocity_mps <= 1.0):
            raise InputError(
                "invalid friction regularisation speed",
                field="couplers.friction_velocity_mps",
                value=self.friction_velocity_mps,
                allowed="1e-5 .. 1 m/s",
            )
        for name in ("draft_capacity_n", "buff_capacity_n"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise InputError(
                    "a coupler capacity must be a force > 0 (or none: not checked)",
                    field=f"couplers.{name}",
                    value=value,
                )
        for name in ("draft_stiffness_n_per_m", "buff_stiffness_n_per_m", "solid_stiffness_n_per_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InputError("coupler stiffness must be > 0", field=f"couplers.{name}", value=value)
        for name in ("draft_damping_n_s_per_m", "buff_damping_n_s_per_m", "slack_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise InputError("must be >= 0", field=f"couplers.{name}", value=value)
        for name in ("draft_travel_m", "buff_travel_m", "smoothing_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InputError("must be > 0", field=f"couplers.{name}", value=value)
        if self.solid_stiffness_n_per_m < max(self.draft_stiffness_n_per_m, self.buff_stiffness_n_per_m):
            raise InputError(
                "the solid stiffness must be at least the draft and buff stiffness",
                field="couplers.solid_stiffness_n_per_m",
                value=self.solid_stiffness_n_per_m,
            )
        if self.smoothing_m > 0.25 * min(self.draft_travel_m, self.buff_travel_m) or (
            self.slack_m > 0 and self.smoothing_m > 0.25 * self.slack_m
        ):
            raise InputError(
                "the smoothing width must be small against the slack and the travel",
                field="couplers.smoothing_m",
                value=self.smoothing_m,
                allowed="<= 1/4 of slack_m (if any) and of the travels",
            )

    @classmethod
    def stiff(cls, stiffness_n_per_m: float = 1.0e9, damping_n_s_per_m: float = 2.0e6) -> CouplerModel:
        """A slackless, very stiff coupling (close to a rigid train), for comparisons with the
        single-point model."""
        return cls(
            draft_stiffness_n_per_m=stiffness_n_per_m,
            buff_stiffness_n_per_m=stiffness_n_per_m,
            draft_damping_n_s_per_m=damping_n_s_per_m,
            buff_damping_n_s_per_m=damping_n_s_per_m,
            slack_m=0.0,
            solid_stiffness_n_per_m=stiffness_n_per_m,
            draft_capacity_n=None,
            buff_capacity_n=None,
            friction_ratio=0.0,
        )

    def as_row(self) -> np.ndarray:
        """Parameters in the order the kernel reads them (see ``kernel.C_*``)."""
        return np.array(
            [
                self.draft_stiffness_n_per_m,
                self.buff_stiffness_n_per_m,
                self.draft_damping_n_s_per_m,
                self.buff_damping_n_s_per_m,
                0.5 * self.slack_m,
                self.draft_travel_m,
                self.buff_travel_m,
                self.solid_stiffness_n_per_m,
                self.smoothing_m,
                self.friction_ratio,
                self.friction_velocity_mps,
            ]
        )


@dataclass(frozen=True)
class BrakePropagation:
    """How the brake command reaches the vehicles' friction brakes.

    Attributes:
        speed_mps: propagation speed of the command along the train [m/s]; None: every vehicle brakes
            at once (as the single-point model assumes; also electronically controlled brakes).
            About 250 m/s for UIC air brakes (the minimum UIC 540 asks of freight brakes; ASSUMPTION
            where a value is used).
        source: ``head`` (the driver's brake valve) or ``locomotives`` (every locomotive vents the
            brake pipe, as distributed-power locomotives do): the delay of a vehicle is its distance
            to the nearest source divided by the speed.
        build_up_s: time constant of the brake-cylinder pressure build-up and release (first-order lag)
            [s]; 0: immediate. (UIC brake position "P" fills the cylinders in 3-5 s, "G" in 18-30 s.)
    """

    speed_mps: float | None = None
    source: Literal["head", "locomotives"] = "head"
    build_up_s: float = 0.0

    def __post_init__(self) -> None:
        if self.speed_mps is not None and not (math.isfinite(self.speed_mps) and self.speed_mps > 0):
            raise InputError(
                "the brake propagation speed must be > 0",
                field="brakes.propagation_speed_mps",
                value=self.speed_mps,
            )
        if self.source not in ("head", "locomotives"):
            raise InputError(
                "unknown brake command source",
                field="brakes.propagation_from",
                value=self.source,
                allowed="head, locomotives",
            )
        if not (math.isfinite(self.build_up_s) and self.build_up_s >= 0):
            raise InputError("must be >= 0 s", field="brakes.build_up_s", value=self.build_up_s)


@dataclass(frozen=True)
class Locomotive:
    """A powered vehicle of the multi-point train.

    Attributes:
        vehicle: index of the vehicle in the (arranged) formation, 0 = head.
        share: share of the train's effort curve (and of its regenerative braking) this vehicle
            provides [-].
        traction: its own maximum tractive effort over speed [N]; None: ``share x`` the train's curve.
    """

    vehicle: int
    share: float | None = None
    traction: EffortCurve | None = None


@dataclass(frozen=True)
class MultiPointSettings:
    """Settings of the multi-point model (SI units).

    Attributes:
        couplers: the coupling model used between every pair of vehicles.
        coupler_overrides: other models for some couplings, by coupling index (0 = between vehicles
            0 and 1).
        locomotive_positions: where the powered vehicles go, in formation order (e.g. ``(0, 51)``: the
            first powered vehicle at the head, the second as vehicle 51); the other vehicles keep their
            order. None: the formation as given.
        locomotives: powered vehicles and their shares of traction; None: every ``powered`` vehicle, equal
            shares.
        braking_distribution: friction braking force per vehicle proportional to its ``mass`` (default)
            or ``equal`` per vehicle.
        electric_braking_at: regenerative braking at the ``locomotives`` (default, where it happens) or
            spread over the ``train`` like the friction brakes.
        brake_propagation: delay of the friction brake command along the train.
        resistance_split: ``terms`` (default): terms of one vehicle type to the vehicles of that type,
            whole-train terms by mass; ``mass``: the train's whole law by mass.
        initial_couplers: ``neutral`` (every coupling in the middle of its slack), ``stretched`` or
            ``bunched`` (slack taken up in draft or buff) at the start.
        time_step_s: largest step of the implicit integrator [s].
        force_tolerance_n: step-size control: a step whose coupler forces at its end depart from their
            quadratic extrapolation through the three previous step ends by more than this is repeated
            shorter, and the next step is sized for it [N]; None: fixed steps of ``time_step_s``.
        min_time_step_s: smallest step of the step-size control [s].
        record_interval_s: interval between recorded states [s] (extremes are taken at every step).
        speed_time_constant_s: the controller that follows a reference profile closes a speed error
            with this time constant [s] (within the traction and braking limits).
        standstill_speed_mps: resistance and brakes oppose motion through ``tanh(v / this)``, a
            regularised dry friction that holds a vehicle at rest without a switch [m/s].
        stop_window_m: a stop counts when the train is at rest with its head this close to the stop [m].
        lookahead: anticipate the brake delay when following a reference (start braking the mean
            delay earlier).
        traction_ramp_s: when following a reference, the traction command rises from 0 to full in
            this time at the fastest [s] (0: at once, as the single-point model); drivers of long
            trains notch up gradually to take up the slack without snatches.
    """

    couplers: CouplerModel = field(default_factory=CouplerModel)
    coupler_overrides: Mapping[int, CouplerModel] = field(default_factory=dict)
    locomotive_positions: tuple[int, ...] | None = None
    locomotives: tuple[Locomotive, ...] | None = None
    braking_distribution: Literal["mass", "equal"] = "mass"
    electric_braking_at: Literal["locomotives", "train"] = "locomotives"
    brake_propagation: BrakePropagation = field(default_factory=BrakePropagation)
    resistance_split: Literal["terms", "mass"] = "terms"
    initial_couplers: Literal["neutral", "stretched", "bunched"] = "neutral"
    time_step_s: float = 0.05
    force_tolerance_n: float | None = None
    min_time_step_s: float = 1.0e-3
    record_interval_s: float = 1.0
    speed_time_constant_s: float = 1.0
    standstill_speed_mps: float = 0.001
    stop_window_m: float = 2.0
    lookahead: bool = True
    traction_ramp_s: float = 0.0

    def __post_init__(self) -> None:
        checks = {
            "time_step_s": (self.time_step_s, 1e-4 <= self.time_step_s <= 1.0, "1e-4 .. 1 s"),
            "record_interval_s": (self.record_interval_s, self.record_interval_s > 0, "> 0 s"),
            "min_time_step_s": (self.min_time_step_s, 1e-5 <= self.min_time_step_s <= 1.0, "1e-5 .. 1 s"),
            "force_tolerance_n": (
                self.force_tolerance_n or 1.0,
                self.force_tolerance_n is None or self.force_tolerance_n > 0,
                "> 0 N, or none for fixed steps",
            ),
            "speed_time_constant_s": (
                self.speed_time_constant_s,
                self.speed_time_constant_s >= 2 * self.time_step_s,
                ">= 2 x time_step_s",
            ),
            "standstill_speed_mps": (
                self.standstill_speed_mps,
                1e-4 <= self.standstill_speed_mps <= 0.1,
                "1e-4 .. 0.1 m/s",
            ),
            "stop_window_m": (self.stop_window_m, self.stop_window_m > 0, "> 0 m"),
            "traction_ramp_s": (self.traction_ramp_s, 0 <= self.traction_ramp_s <= 600, "0 .. 600 s"),
        }
        for name, (value, ok, allowed) in checks.items():
            if not (ok and math.isfinite(value)):
                raise InputError("invalid multi-point setting", field=name, value=value, allowed=allowed)
        for name, value, allowed in (
            ("braking_distribution", self.braking_distribution, ("mass", "equal")),
            ("electric_braking_at", self.electric_braking_at, ("locomotives", "train")),
            ("resistance_split", self.resistance_split, ("terms", "mass")),
            ("initial_couplers", self.initial_couplers, ("neutral", "stretched", "bunched")),
        ):
            if value not in allowed:
                raise InputError("not an allowed value", field=name, value=value, allowed=", ".join(allowed))
        object.__setattr__(self, "coupler_overrides", dict(self.coupler_overrides))


# ---------------------------------------------------------------------------------------------- the train
@dataclass(frozen=True, eq=False)
class MultiPointTrain:
    """A train as the multi-point integrator sees it (per-vehicle arrays, head first, SI units).

    Attributes:
        train: the single-point train it was built from (effort curves, braking, electrics).
        settings: the multi-point settings.
        vehicles: the vehicles, head first (after ``locomotive_positions``).
        mass_kg: static mass of each vehicle including load [kg].
        inertial_mass_kg: rho_i x m_i [kg]; sums to the train's inertial mass.
        length_m: length over couplers of each vehicle [m].
        resistance: running-resistance law of each vehicle [N over m/s].
        locomotives: the powered vehicles with their traction.
        traction_curves: effort curve of each locomotive [N over m/s] (same order as ``locomotives``).
        regen_share: share of the train's regenerative braking at each vehicle [-] (sums to 1).
        brake_share: share of the train's friction braking at each vehicle [-] (sums to 1).
        brake_delay_s: delay of the brake command at each vehicle [s].
        couplers: the model of each of the ``n - 1`` couplings.
    """

    train: Train
    settings: MultiPointSettings
    vehicles: tuple[Vehicle, ...]
    mass_kg: np.ndarray
    inertial_mass_kg: np.ndarray
    length_m: np.ndarray
    resistance: tuple[Quadratic, ...]
    locomotives: tuple[Locomotive, ...]
    traction_curves: tuple[EffortCurve, ...]
    regen_share: np.ndarray
    brake_share: np.ndarray
    brake_delay_s: np.ndarray
    couplers: tuple[CouplerModel, ...]
    notes: tuple[str, ...] = ()

    @property
    def n_vehicles(self) -> int:
        return len(self.vehicles)

    @property
    def locomotive_indices(self) -> np.ndarray:
        """Index of each locomotive in the formation."""
        return np.array([loco.vehicle for loco in self.locomotives], dtype=np.int64)

    @property
    def total_mass_kg(self) -> float:
        return float(self.mass_kg.sum())

    def nominal_offsets_m(self) -> np.ndarray:
        """Distance of each vehicle's front from the head's front at nominal coupler spacing [m]."""
        return np.concatenate([[0.0], np.cumsum(self.length_m[:-1])])

    def coupler_positions_m(self, head_m: float = 0.0) -> np.ndarray:
        """Nominal position of each coupling for a head at ``head_m`` [m]."""
        return head_m - np.cumsum(self.length_m[:-1])


_TERM_LABEL = re.compile(r"^(?P<family>.+): (?P<count>\d+) x (?P<name>.+)$")


def split_resistance(
    train: Train, vehicles: Sequence[Vehicle], mode: str = "terms"
) -> tuple[tuple[Quadratic, ...], list[str]]:
    """Running-resistance law of every vehicle, adding up to the train's law.

    ``terms``: a term labelled ``"<family>: <n> x <name>"`` (trainsim YAML, a term of vehicle type
    ``<name>``) goes to the n vehicles of that name, 1/n each; railtoolkit terms of the "traction unit"
    to the powered vehicles and of the "cars" to the others, by mass; every other term (whole-train laws)
    by mass. ``mass``: the whole law by mass. Mass shares are exact for the laws that are proportional to
    mass (per-mass, specific N/kN, Strahl...); for a whole-train Davis law they put the air drag on every
    vehicle by mass, where it really acts mostly on the head.
    """
    masses = np.array([v.total_mass_kg for v in vehicles])
    names = [v.name for v in vehicles]
    powered = np.array([v.powered for v in vehicles])
    laws = [[0.0, 0.0, 0.0] for _ in vehicles]
    notes: list[str] = []

    def add(idx: np.ndarray, weights: np.ndarray, law: Quadratic) -> None:
        weights = weights / weights.sum()
        for i, w in zip(idx, weights, strict=True):
            laws[i][0] += w * law.c0
            laws[i][1] += w * law.c1
            laws[i][2] += w * law.c2

    everyone = np.arange(len(vehicles))
    for term in train.resistance:
        if mode == "terms":
            match = _TERM_LABEL.match(term.label)
            if match:
                idx = np.array([i for i, n in enumerate(names) if n == match["name"]], dtype=int)
                if len(idx) == int(match["count"]):
                    add(idx, np.ones(len(idx)), term.law)
                    continue
            if "traction unit" in term.label and powered.any():
                add(np.flatnonzero(powered), masses[powered], term.law)
                continue
            if "cars" in term.label and (~powered).any():
                add(np.flatnonzero(~powered), masses[~powered], term.law)
                continue
        add(everyone, masses, term.law)
        if mode == "terms":
            notes.append(f"resistance term '{term.label}' split over the vehicles by mass")
    out = tuple(Quadratic(*law) for law in laws)
    total = train.resistance_law
    got = Quadratic(sum(q.c0 for q in out), sum(q.c1 for q in out), sum(q.c2 for q in out))
    for a, b in ((got.c0, total.c0), (got.c1, total.c1), (got.c2, total.c2)):
        if abs(a - b) > 1e-9 * max(1.0, abs(b)):
            raise AssertionError("per-vehicle resistance laws do not add up to the train's law")
    return out, notes


def _arranged(vehicles: tuple[Vehicle, ...], positions: Sequence[int] | None) -> tuple[Vehicle, ...]:
    if positions is None:
        return vehicles
    powered = [v for v in vehicles if v.powered]
    others = [v for v in vehicles if not v.powered]
    n = len(vehicles)
    if len(positions) != len(powered):
        raise InputError(
            "give one position per powered vehicle",
            field="locomotive_positions",
            value=list(positions),
            allowed=f"{len(powered)} positions (the train has {len(powered)} powered vehicles)",
        )
    if len(set(positions)) != len(positions) or any(not 0 <= p < n for p in positions):
        raise InputError(
            "locomotive positions must be distinct vehicle indices",
            field="locomotive_positions",
            value=list(positions),
            allowed=f"0 .. {n - 1}",
        )
    slots: list[Vehicle | None] = [None] * n
    for p, v in zip(positions, powered, strict=True):
        slots[p] = v
    rest = iter(others)
    return tuple(s if s is not None else next(rest) for s in slots)


def _inertial_masses(train: Train, vehicles: tuple[Vehicle, ...], masses: np.ndarray) -> np.ndarray:
    """rho_i m_i, scaled so that the sum is the train's rho m (the single-point model's inertia)."""
    extra = np.array([(v.rotating_mass_factor - 1.0) for v in vehicles]) * masses
    wanted = (train.rotating_mass_factor - 1.0) * train.mass_kg
    if extra.sum() > 0:
        extra *= wanted / extra.sum()
    else:
        extra = (train.rotating_mass_factor - 1.0) * masses
    return masses + extra


def brake_delays(lengths: np.ndarray, sources: np.ndarray, propagation: BrakePropagation) -> np.ndarray:
    """Delay of the brake command at each vehicle's centre [s]: distance to the nearest source
    vehicle's centre over the propagation speed (0 without propagation)."""
    n = len(lengths)
    if propagation.speed_mps is None:
        return np.zeros(n)
    centre = np.concatenate([[0.0], np.cumsum(lengths[:-1])]) + 0.5 * lengths
    distance = np.min(np.abs(centre[:, None] - centre[None, sources]), axis=1)
    return distance / propagation.speed_mps


def build_multipoint_train(
    train: Train,
    settings: MultiPointSettings | None = None,
    *,
    vehicle_resistance: Sequence[Quadratic] | None = None,
) -> MultiPointTrain:
    """The multi-point model of ``train``.

    Args:
        train: a train with its formation (``train.vehicles``), e.g. from a trainsim YAML file.
        settings: multi-point settings (couplers, locomotives, braking...).
        vehicle_resistance: running-resistance law of every vehicle (after ``locomotive_positions``),
            instead of splitting the train's terms.

    Raises:
        InputError: a train without formation, no powered vehicle, bad locomotive data.
    """
    settings = settings or MultiPointSettings()
    if len(train.vehicles) < 2:
        raise InputError(
            "the multi-point model needs the train's formation (at least two vehicles); "
            "give 'formation' in the train file instead of the whole-train mass",
            field="formation",
            value=len(train.vehicles),
        )
    vehicles = _arranged(train.vehicles, settings.locomotive_positions)
    n = len(vehicles)
    masses = np.array([v.total_mass_kg for v in vehicles], dtype=float)
    lengths = np.array([v.length_m for v in vehicles], dtype=float)
    if np.any(lengths <= 0):
        raise InputError("every vehicle needs a length > 0", field="formation.length_m")
    if abs(masses.sum() - train.mass_kg) > 1e-6 * train.mass_kg:
        raise InputError(
            "the vehicles' masses do not add up to the train's mass",
            field="formation",
            value=(float(masses.sum()), train.mass_kg),
        )
    notes: list[str] = []
    if vehicle_resistance is not None:
        if len(vehicle_resistance) != n:
            raise InputError(
                "give one resistance law per vehicle",
                field="vehicle_resistance",
                value=len(vehicle_resistance),
            )
        resistance = tuple(vehicle_resistance)
    else:
        resistance, split_notes = split_resistance(train, vehicles, settings.resistance_split)
        notes += split_notes

    # locomotives and their effort
    if settings.locomotives is not None:
        locos = tuple(settings.locomotives)
    else:
        locos = tuple(Locomotive(i) for i, v in enumerate(vehicles) if v.powered)
    if not locos:
        raise InputError(
            "the multi-point model needs to know which vehicles pull: mark them 'powered: true' in "
            "the formation, or list 'locomotives' in the multi-point settings",
            field="formation.powered",
        )
    idx = [loco.vehicle for loco in locos]
    if len(set(idx)) != len(idx) or any(not 0 <= i < n for i in idx):
        raise InputError(
            "locomotives must be distinct vehicle indices",
            field="locomotives",
            value=idx,
            allowed=f"0 .. {n - 1}",
        )
    given = [loco.share for loco in locos]
    if all(s is None for s in given):
        shares = [1.0 / len(locos)] * len(locos)
    elif any(s is None for s in given):
        raise InputError("give a share for every locomotive or for none", field="locomotives.share")
    else:
        shares = [float(s) for s in given]  # type: ignore[arg-type]
        if any(not s >= 0 for s in shares) or abs(sum(shares) - 1.0) > 1e-6:
            raise InputError(
                "locomotive shares must be >= 0 and add up to 1",
                field="locomotives.share",
                value=shares,
            )
    locos = tuple(dataclasses.replace(loco, share=s) for loco, s in zip(locos, shares, strict=True))
    curves = tuple(
        loco.traction
        if loco.traction is not None
        else train.traction.scaled(loco.share, label=f"{loco.share:g} x train")
        for loco in locos
    )
    if any(loco.traction is not None for loco in locos):
        notes.append("some locomotives have their own effort curve: the total differs from the train's")

    # braking shares
    brake_share = masses / masses.sum() if settings.braking_distribution == "mass" else np.full(n, 1.0 / n)
    regen_share = np.zeros(n)
    if settings.electric_braking_at == "locomotives":
        for loco in locos:
            regen_share[loco.vehicle] = loco.share
    else:
        regen_share = brake_share.copy()
    sources = np.array([0] if settings.brake_propagation.source == "head" else idx, dtype=int)
    delays = brake_delays(lengths, sources, settings.brake_propagation)

    # couplers
    for k in settings.coupler_overrides:
        if not 0 <= k < n - 1:
            raise InputError(
                "no coupling with that index", field="coupler_overrides", value=k, allowed=f"0 .. {n - 2}"
            )
    couplers = tuple(settings.coupler_overrides.get(k, settings.couplers) for k in range(n - 1))

    return MultiPointTrain(
        train=train,
        settings=settings,
        vehicles=vehicles,
        mass_kg=masses,
        inertial_mass_kg=_inertial_masses(train, vehicles, masses),
        length_m=lengths,
        resistance=resistance,
        locomotives=locos,
        traction_curves=curves,
        regen_share=regen_share,
        brake_share=brake_share,
        brake_delay_s=delays,
        couplers=couplers,
        notes=tuple(notes),
    )
