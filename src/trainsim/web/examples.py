"""The worked examples shipped with the web application (copies of the repository's ``examples/``).

They are package data, so that an installed trainsim (not only a source checkout) can start from
them; ``tests/web/test_web_examples.py`` checks that the copies equal the repository's files.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from trainsim.io import trainsim_yaml as tsy
from trainsim.model.scenario import RunSettings

EXAMPLES_DIR = Path(__file__).parent / "example_files"

#: example name -> one line saying what it is (shown in the page)
DESCRIPTIONS: dict[str, str] = {
    "metro_b": "Source 002's type B metro on its 4-station line (4.59 km)",
    "loco_001": "Source 001's BB 60000 locomotive with 12 carriages",
    "freight_000": "Heavy freight train on a 60 km line with gradients, curves and tunnels (source 000)",
}


@dataclass(frozen=True)
class Example:
    """A shipped scenario: its train file, route file and run settings."""

    name: str
    title: str
    description: str
    train_path: Path
    route_path: Path
    settings: RunSettings


@lru_cache(maxsize=16)
def train_spec(name: str) -> tsy.TrainSpec:
    """The validated train spec of an example (read once; never modified)."""
    return tsy.read_train_spec(examples()[name].train_path)


@lru_cache(maxsize=16)
def route_spec(name: str) -> tsy.RouteSpec:
    """The validated route spec of an example (read once; never modified)."""
    return tsy.read_route_spec(examples()[name].route_path)


@lru_cache(maxsize=1)
def examples() -> dict[str, Example]:
    """The shipped examples by name, in the order of :data:`DESCRIPTIONS`."""
    out = {}
    for name, description in DESCRIPTIONS.items():
        folder = EXAMPLES_DIR / name
        spec = tsy.read_scenario_spec(folder / "scenario.yaml")
        out[name] = Example(
            name=name,
            title=spec.name,
            description=description,
            train_path=folder / "train.yaml",
            route_path=folder / "route.yaml",
            settings=spec.settings.build(),
        )
    return out
