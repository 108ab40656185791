"""The names of railtoolkit / TrainRuns.jl files that format detection needs, without their reader.

The loader recognises railtoolkit files by these schema URLs; :mod:`trainsim.io.railtoolkit` (the
reader, imported only when such a file is read) takes them from here (issue 14: a `trainsim run` of a
trainsim scenario does not import the railtoolkit reader).
"""

from __future__ import annotations

from typing import Literal

ROLLING_STOCK_SCHEMA_URL = "https://railtoolkit.org/schema/rolling-stock.json"
PATH_SCHEMA_URL = "https://railtoolkit.org/schema/running-path.json"

#: TrainRuns.jl mass models -> where trainsim applies the line resistance.
MASS_MODELS: dict[str, Literal["head", "train_length"]] = {
    "mass_point": "head",
    "homogeneous_strip": "train_length",
}
