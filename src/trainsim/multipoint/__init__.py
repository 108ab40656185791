"""Multi-point train model (source 000): one mass per vehicle, couplers as spring-dampers with slack,
distributed power, braking per vehicle with a propagation delay, in-train forces.

    from trainsim.multipoint import MultiPointSettings, CouplerModel, run_multipoint_fastest
    result = run_multipoint_fastest(train, route, MultiPointSettings(locomotive_positions=(0, 51)))
    result.max_draft, result.max_buff, result.summary()

See docs/MULTIPOINT.md.
"""

from trainsim.multipoint.model import (
    BrakePropagation,
    CouplerModel,
    Locomotive,
    MultiPointSettings,
    MultiPointTrain,
    build_multipoint_train,
    split_resistance,
)
from trainsim.multipoint.result import CouplerExtreme, EnergyAccount, MultiPointResult
from trainsim.multipoint.simulate import (
    MultiPointSession,
    MultiPointState,
    SpeedProfile,
    follow_profile,
    run_multipoint_fastest,
)

__all__ = [
    "BrakePropagation",
    "CouplerExtreme",
    "CouplerModel",
    "EnergyAccount",
    "Locomotive",
    "MultiPointResult",
    "MultiPointSession",
    "MultiPointSettings",
    "MultiPointState",
    "MultiPointTrain",
    "SpeedProfile",
    "build_multipoint_train",
    "follow_profile",
    "run_multipoint_fastest",
    "split_resistance",
]
