"""Helpers of the interchange tests: where the hand-written test data are, and a run helper."""

from __future__ import annotations

from pathlib import Path

import trainsim
from trainsim.model.scenario import RunSettings, Scenario

REPO = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parent / "data"
EXAMPLES = REPO / "examples"

#: The test line's line-resistance formulas (the railML 3 file does not carry them).
FORMULAS = {"curve_formula": "roeckl", "tunnel_formula": "wang"}
#: The round-trip tolerance of issue 6: running time and energy equal within 0.01 %.
ROUND_TRIP = 1e-4


def run(train, route, step: float = 10.0):
    """The fastest run of a train on a route (10 m steps)."""
    return trainsim.run(Scenario("test", train, route, RunSettings(max_step_m=step)))


def relative(a: float, b: float) -> float:
    return abs(a - b) / max(abs(b), 1e-12)


def railml(name: str, **replace: str) -> str:
    """A test data file's text with replacements (to derive variants with errors)."""
    text = (DATA / name).read_text(encoding="utf-8")
    for old, new in replace.items():
        assert old in text, old
        text = text.replace(old, new)
    return text


def line_of(text: str, needle: str) -> int:
    """1-based line of the first occurrence of ``needle`` in ``text``."""
    return text[: text.index(needle)].count("\n") + 1
