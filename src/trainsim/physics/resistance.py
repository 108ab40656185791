"""Running-resistance families, each reduced to a :class:`~trainsim.model.laws.Quadratic` in SI.

Every function returns ``F(v) = c0 + c1 v + c2 v^2`` [N, v in m/s], whatever units its source
writes the law in; the conversion is done here and nowhere else. Sources:

* 000: ATO train dynamic models (Wang et al. via the seed document), ``R_b = m (a1 + a2 v^2)``.
* 001: acceleration of a locomotive-hauled train, French RAV ``A + B V + C V^2``.
* 002: Cui et al., urban subway modelling, eq. 4 (Davis) and table 2.
* Wende, *Fahrdynamik des Schienenverkehrs* (2003), p. 151-153, as implemented in TrainRuns.jl.
* ALTRIOS (NREL), ``train_res`` bearing / rolling / Davis-b / aerodynamic terms.
"""

from __future__ import annotations

from collections.abc import Callable

from trainsim.constants import (
    AIR_DENSITY,
    KMH,
    KN,
    PERMILLE,
    STANDARD_GRAVITY,
    TONNE,
    WENDE_AIR_SPEED_MARGIN,
    WENDE_REFERENCE_SPEED,
)
from trainsim.errors import InputError
from trainsim.model.laws import Quadratic

__all__ = [
    "RESISTANCE_FAMILIES",
    "altrios",
    "davis",
    "davis_kn_kmh",
    "per_mass",
    "rav",
    "rav_carriage_4axle",
    "rav_locomotive_bb60000",
    "sauthoff",
    "specific_n_per_kn",
    "strahl",
    "wende_traction_unit",
]


def _require_positive(name: str, value: float) -> None:
    if not value > 0:
        raise InputError("must be > 0", field=f"resistance.{name}", value=value, allowed="> 0")


def _from_kmh(a: float, b_per_kmh: float, c_per_kmh2: float, unit_n: float = 1.0) -> Quadratic:
    """A law ``a + b V + c V^2`` in ``unit_n`` newtons with V in km/h, as a SI Quadratic."""
    # V [km/h] = v [m/s] / KMH, so the linear term scales by 1/KMH and the quadratic one by 1/KMH^2.
    return Quadratic(a * unit_n, b_per_kmh * unit_n / KMH, c_per_kmh2 * unit_n / KMH**2)


def davis(a_n: float, b_n_s_per_m: float, c_n_s2_per_m2: float) -> Quadratic:
    """Davis law ``R = A + B v + C v^2`` already in SI (source 002 eq. 4; Davis 1926).

    Args:
        a_n: constant term A [N].
        b_n_s_per_m: linear term B [N s/m].
        c_n_s2_per_m2: quadratic term C [N s^2/m^2].

    Returns:
        The resistance [N] over speed [m/s].
    """
    return Quadratic(a_n, b_n_s_per_m, c_n_s2_per_m2)


def davis_kn_kmh(a_kn: float, b_kn_per_kmh: float, c_kn_per_kmh2: float) -> Quadratic:
    """Whole-train Davis law in kN with V in km/h (source 002 eq. 4 with the table 2 parameters).

    Source 002 gives "basic resistance parameter 1..3" = 2.43, 0.02997, 0.00078 without units. Read
    as kN with V in km/h they give 9.82 kN at 80 km/h for the 288.2 t train, i.e. 3.47 N/kN, a usual
    metro value; read as N/kN they would give three times that. This function applies the kN reading.

    Args:
        a_kn: constant term [kN].
        b_kn_per_kmh: linear term [kN/(km/h)].
        c_kn_per_kmh2: quadratic term [kN/(km/h)^2].

    Returns:
        The resistance [N] over speed [m/s].
    """
    return _from_kmh(a_kn, b_kn_per_kmh, c_kn_per_kmh2, unit_n=KN)


def per_mass(mass_kg: float, a1_n_per_kg: float, a2_n_s2_per_kg_m2: float) -> Quadratic:
    """Basic resistance proportional to mass, ``R_b = m (a1 + a2 v^2)`` (source 000, basic resistance).

    Args:
        mass_kg: train mass m [kg].
        a1_n_per_kg: a1 [N/kg] (= m/s^2).
        a2_n_s2_per_kg_m2: a2 [N s^2/(kg m^2)] (= 1/m).

    Returns:
        The resistance [N] over speed [m/s].
    """
    _require_positive("mass", mass_kg)
    return Quadratic(mass_kg * a1_n_per_kg, 0.0, mass_kg * a2_n_s2_per_kg_m2)


def specific_n_per_kn(
    mass_kg: float, a: float, b: float, c: float, *, gravity_mps2: float = STANDARD_GRAVITY
) -> Quadratic:
    """Specific resistance ``w0 = a + b V + c V^2`` [N/kN] with V in km/h, force ``w0 m g / 1000``.

    The form of the Chinese traction rules (TB/T 1407, cited by source 002) and of the Russian PTR
    (source 004): a resistance per unit weight, numerically equal to per mille.

    Args:
        mass_kg: mass the specific resistance applies to [kg].
        a: constant term [N/kN].
        b: linear term [N/kN per km/h].
        c: quadratic term [N/kN per (km/h)^2].
        gravity_mps2: g that turns the mass into a weight [m/s^2] (the source's convention).

    Returns:
        The resistance [N] over speed [m/s].
    """
    _require_positive("mass", mass_kg)
    return _from_kmh(a, b, c, unit_n=mass_kg * gravity_mps2 * PERMILLE)


def rav(a_n: float, b_n_per_kmh: float, c_n_per_kmh2: float) -> Quadratic:
    """French running resistance ``RAV = A + B V + C V^2`` in N with V in km/h (source 001, "RAV losses").

    Args:
        a_n: A, rolling and bearing resistance [N].
        b_n_per_kmh: B, flange friction and hysteresis [N/(km/h)].
        c_n_per_kmh2: C, aerodynamic term [N/(km/h)^2].

    Returns:
        The resistance [N] over speed [m/s].
    """
    return _from_kmh(a_n, b_n_per_kmh, c_n_per_kmh2)


def rav_locomotive_bb60000(mass_kg: float, axles: int) -> Quadratic:
    """RAV of a BB 60000 locomotive, ``6.5 M + 130 N_e + 0.1 M V + 0.3 V^2`` (source 001, example).

    Units reading (the source gives none): RAV in N with M in t and V in km/h. It gives 4.7 kN for
    a 72 t, 4-axle locomotive at 100 km/h (6.5 N/kN), a plausible value; the source's own
    ``F_wheel = RAV + M g i / 1000`` sums it with a grade force in N.

    Args:
        mass_kg: locomotive mass M [kg] (converted to t for the formula).
        axles: number of axles N_e [-].

    Returns:
        The resistance [N] over speed [m/s].
    """
    _require_positive("mass", mass_kg)
    _require_positive("axles", axles)
    m_t = mass_kg / TONNE
    return rav(6.5 * m_t + 130.0 * axles, 0.1 * m_t, 0.3)


def rav_carriage_4axle(mass_kg: float) -> Quadratic:
    """RAV of a standard 4-axle carriage, ``12 M + 0.09 M V + 0.0044 M V^2`` (source 001, example).

    Units reading as for :func:`rav_locomotive_bb60000`: N with M in t and V in km/h, i.e. a
    specific resistance of ``1.2 + 0.009 V + 0.00044 V^2`` daN/t (6.6 N/kN at 100 km/h, a value
    typical of freight wagons).

    Args:
        mass_kg: carriage mass M [kg] (converted to t for the formula).

    Returns:
        The resistance [N] over speed [m/s].
    """
    _require_positive("mass", mass_kg)
    m_t = mass_kg / TONNE
    return rav(12.0 * m_t, 0.09 * m_t, 0.0044 * m_t)


def strahl(
    mass_kg: float, f0_permille: float, f2_permille: float, *, gravity_mps2: float = STANDARD_GRAVITY
) -> Quadratic:
    """Strahl's law for freight wagons, ``m g (f0 + f2 (v/v00)^2) / 1000`` with v00 = 100 km/h.

    Reference: Wende (2003) p. 153; TrainRuns.jl ``calcFreightWagonsResistance``.

    Args:
        mass_kg: mass of the wagons [kg].
        f0_permille: basic resistance coefficient f0 [per mille of weight].
        f2_permille: air resistance coefficient f2 at v00 [per mille of weight].
        gravity_mps2: g [m/s^2] (TrainRuns.jl: 9.80665).

    Returns:
        The resistance [N] over speed [m/s].
    """
    _require_positive("mass", mass_kg)
    weight_ratio_n = mass_kg * gravity_mps2 * PERMILLE
    return Quadratic(
        weight_ratio_n * f0_permille, 0.0, weight_ratio_n * f2_permille / WENDE_REFERENCE_SPEED**2
    )


def _air_term(force_at_v00_n: float) -> Quadratic:
    """``F2 ((v + dv_air) / v00)^2`` expanded into a Quadratic (Wende 2003; head-wind allowance)."""
    dv, v00 = WENDE_AIR_SPEED_MARGIN, WENDE_REFERENCE_SPEED
    k = force_at_v00_n / v00**2
    return Quadratic(k * dv * dv, 2.0 * k * dv, k)


def sauthoff(
    mass_kg: float,
    f0_permille: float,
    f1_permille: float,
    f2_permille: float,
    *,
    gravity_mps2: float = STANDARD_GRAVITY,
) -> Quadratic:
    """Sauthoff's law for passenger coaches (Wende 2003 p. 153; TrainRuns.jl
    ``calcPassengerWagonsResistance``):

        m g (f0 + f1 v/v00 + f2 ((v + dv_air)/v00)^2) / 1000,   v00 = 100 km/h, dv_air = 15 km/h.

    Args:
        mass_kg: mass of the coaches [kg].
        f0_permille: basic resistance coefficient [per mille of weight].
        f1_permille: rolling (linear) coefficient at v00 [per mille of weight].
        f2_permille: air resistance coefficient at v00 [per mille of weight].
        gravity_mps2: g [m/s^2] (TrainRuns.jl: 9.80665).

    Returns:
        The resistance [N] over speed [m/s].
    """
    _require_positive("mass", mass_kg)
    weight_ratio_n = mass_kg * gravity_mps2 * PERMILLE
    basic = Quadratic(weight_ratio_n * f0_permille, weight_ratio_n * f1_permille / WENDE_REFERENCE_SPEED)
    return basic + _air_term(weight_ratio_n * f2_permille)


def wende_traction_unit(
    mass_kg: float,
    driven_mass_kg: float,
    f_driven_permille: float,
    f_carrying_permille: float,
    f_air_permille: float,
    *,
    gravity_mps2: float = STANDARD_GRAVITY,
) -> Quadratic:
    """Traction-unit resistance after Wende (2003) p. 151, as TrainRuns.jl's
    ``calcTractionUnitResistance``:

        f_td0 m_td g + f_tc0 (m - m_td) g + F_t2 ((v + dv_air)/v00)^2,   all f in per mille / 1000,

    with ``F_t2 = f_air / 1000 x m g``: the air coefficient is given in per mille of the traction
    unit's whole weight (the railtoolkit ``air_resistance`` field), not as a force.

    Args:
        mass_kg: traction unit mass m [kg].
        driven_mass_kg: mass on the driven axles m_td [kg], 0 < m_td <= m.
        f_driven_permille: basic resistance of the driven axles f_td0 [per mille].
        f_carrying_permille: basic resistance of the carrying axles f_tc0 [per mille].
        f_air_permille: air resistance at v00 f_t2 [per mille of m g].
        gravity_mps2: g [m/s^2] (TrainRuns.jl: 9.80665).

    Returns:
        The resistance [N] over speed [m/s].
    """
    _require_positive("mass", mass_kg)
    if not 0 < driven_mass_kg <= mass_kg:
        raise InputError(
            "the mass on driven axles must be positive and at most the vehicle mass",
            field="resistance.driven_mass",
            value=driven_mass_kg,
            allowed=f"0 < m_td <= {mass_kg:g} kg",
        )
    carrying_mass_kg = mass_kg - driven_mass_kg
    g = gravity_mps2
    basic_n = g * PERMILLE * (f_driven_permille * driven_mass_kg + f_carrying_permille * carrying_mass_kg)
    return Quadratic(basic_n) + _air_term(f_air_permille * PERMILLE * mass_kg * g)


def altrios(
    mass_kg: float,
    axles: int,
    bearing_force_per_axle_n: float,
    rolling_ratio: float,
    davis_b_s_per_m: float,
    cd_area_m2: float,
    *,
    gravity_mps2: float = STANDARD_GRAVITY,
) -> Quadratic:
    """US freight resistance in the style of ALTRIOS (NREL) ``train_res`` "point" model:

        axles x bearing + rolling_ratio x W + davis_b v W + rho_air cd_area v^2,   W = m g.

    ALTRIOS reading of the aerodynamic term: the drag equation's factor 1/2 is lumped into the
    drag area, as the Davis C coefficient traditionally does, so ``cd_area_m2`` is ``Cd A / 2``
    of the textbook drag equation and the term is ``rho cd_area v^2`` (rho = 1.225 kg/m^3). Values
    taken from ALTRIOS data files therefore carry over unchanged.

    Args:
        mass_kg: train (or car) mass m [kg].
        axles: number of axles [-].
        bearing_force_per_axle_n: bearing resistance per axle [N].
        rolling_ratio: rolling resistance as a ratio of the weight [-].
        davis_b_s_per_m: Davis b, linear term per unit weight [s/m].
        cd_area_m2: drag area with the 1/2 lumped in (ALTRIOS ``cd_area``) [m^2].
        gravity_mps2: g [m/s^2] (ALTRIOS: 9.80155, ``trainsim.constants.ALTRIOS_GRAVITY``).

    Returns:
        The resistance [N] over speed [m/s].
    """
    _require_positive("mass", mass_kg)
    _require_positive("axles", axles)
    weight_n = mass_kg * gravity_mps2
    return Quadratic(
        axles * bearing_force_per_axle_n + rolling_ratio * weight_n,
        davis_b_s_per_m * weight_n,
        AIR_DENSITY * cd_area_m2,
    )


#: Resistance families by name, for readers that select a law from a file.
RESISTANCE_FAMILIES: dict[str, Callable[..., Quadratic]] = {
    "davis": davis,
    "davis_kn_kmh": davis_kn_kmh,
    "per_mass": per_mass,
    "specific_n_per_kn": specific_n_per_kn,
    "rav": rav,
    "rav_locomotive_bb60000": rav_locomotive_bb60000,
    "rav_carriage_4axle": rav_carriage_4axle,
    "strahl": strahl,
    "sauthoff": sauthoff,
    "wende": wende_traction_unit,
    "altrios": altrios,
}
