"""Small studies on the metro example (source 002) for the batch tests."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
METRO = REPO / "examples" / "metro_b"


def metro_study(**extra: Any) -> dict[str, Any]:
    """A study mapping on the metro train and line; 20 m steps keep every run near 1.5 ms."""
    data: dict[str, Any] = {
        "schema": "trainsim/study",
        "version": 1,
        "name": "test study",
        "base": {
            "name": "metro",
            "train": str(METRO / "train.yaml"),
            "route": str(METRO / "route.yaml"),
            "settings": {"max_step_m": 20},
        },
    }
    data.update(copy.deepcopy(extra))
    return data


#: Axes and samples and a value the reader rejects: 3 x 2 points x 3 samples = 18 runs, 3 of them failed
#: (efficiency 1.2 is out of range), so that executors are compared on failures too.
MIXED = {
    "axes": [
        {"field": "train.formation[*].load_t", "values": [0, 9, 18]},
        {"field": "train.electrical.traction_efficiency", "values": [0.9, 1.2]},
    ],
    "samples": {
        "count": 3,
        "seed": 11,
        "fields": {
            "train.formation[0].mass_t": {
                "distribution": "normal",
                "mean": 1.0,
                "std": 0.02,
                "relative": True,
            },
            "train.electrical.line_voltage_v": {"distribution": "uniform", "low": 900, "high": 1100},
        },
    },
}
