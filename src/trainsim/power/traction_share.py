"""Voltage-limited traction per time step, fed back into a run as a share of tractive effort over position.

At each time step the network gives a train the share ``delivered / asked`` of the traction power
its run asked for (EN 50388 current limitation as the pantograph voltage falls). The step stands
for the stretch of line the train covers around that instant: from half way back to the previous
step's position to half way on to the next one. Laid over the route's positions, these shares make
a piecewise-constant availability of tractive effort, the same kind of input the core already uses
for non-electrified parts (``traction_scale`` per grid interval, ``available`` in the energy
integration), given to it through ``ElectrificationSection.traction_share``. The run over the route
so marked is the train's run under the limitation: the core integrates the motion and the energies
with it, so the books of the run close as for any other run.

The update is monotone: a position's share only ever falls (new share = the share the run had there
times the step's ratio delivered / asked, the lower of that and the previous one), so the iteration
of :func:`trainsim.power.study.run_study` ends; it is consistent when every train gets at least
``1 - tolerance`` of the traction energy it asks.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from trainsim.model.route import Route
from trainsim.model.spans import electrification_cover, split_spans
from trainsim.model.train import Train

__all__ = [
    "SHARE_FLOOR",
    "SHARE_RESOLUTION_M",
    "ShareProfile",
    "route_with_share",
    "step_spans",
]

#: Least share a run is given [-]: a train the line holds at nothing (below Umin1) keeps showing the
#: network what it asks at full supply (its run's traction over its share), so that it can recover.
SHARE_FLOOR = 1e-3

#: Positions where the share changes are rounded to this [m]: the network's own node resolution
#: (trainsim.power.network rounds positions to 0.1 m), and no piece of line shorter than that.
SHARE_RESOLUTION_M = 0.1


@dataclass(frozen=True)
class ShareProfile:
    """A piecewise-constant share of tractive effort over a route's positions.

    Attributes:
        x_m: breakpoints, increasing, from the route's start to its end [m].
        share: the share on ``[x_m[k], x_m[k + 1])``, in [0, 1] [-].
    """

    x_m: np.ndarray
    share: np.ndarray

    @classmethod
    def full(cls, start_m: float, end_m: float) -> ShareProfile:
        """No limitation: share 1 from ``start_m`` to ``end_m`` [m]."""
        return cls(np.array([start_m, end_m]), np.ones(1))

    @property
    def limited(self) -> bool:
        """Whether the share is below 1 anywhere."""
        return bool(np.any(self.share < 1.0))

    def key(self) -> tuple:
        """A hashable form (runs are cached by it)."""
        return tuple(self.x_m.tolist()), tuple(self.share.tolist())

    def at(self, s_m: np.ndarray) -> np.ndarray:
        """The share at positions ``s_m`` [m] (the piece that starts at or before each)."""
        k = np.clip(np.searchsorted(self.x_m, s_m, side="right") - 1, 0, len(self.share) - 1)
        return self.share[k]

    def lowered(self, lo_m: np.ndarray, hi_m: np.ndarray, share: np.ndarray) -> ShareProfile:
        """The profile with ``share[j]`` on ``[lo_m[j], hi_m[j])`` wherever that is lower (positions
        rounded to :data:`SHARE_RESOLUTION_M`; equal neighbouring pieces merged)."""
        a, b = self.x_m[0], self.x_m[-1]
        lo = np.clip(np.round(np.asarray(lo_m) / SHARE_RESOLUTION_M) * SHARE_RESOLUTION_M, a, b)
        hi = np.clip(np.round(np.asarray(hi_m) / SHARE_RESOLUTION_M) * SHARE_RESOLUTION_M, a, b)
        x = np.unique(np.concatenate([self.x_m, lo, hi]))
        mid = 0.5 * (x[:-1] + x[1:])
        value = self.at(mid)
        for l_j, h_j, w_j in zip(lo, hi, np.asarray(share, dtype=float), strict=True):
            inside = (mid >= l_j) & (mid < h_j)
            value[inside] = np.minimum(value[inside], w_j)
        keep = np.concatenate([[True], np.diff(value) != 0.0])
        return ShareProfile(np.append(x[:-1][keep], x[-1]), value[keep])


def step_spans(position_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The stretch of line each of a train's consecutive positions stands for: from half way back
    to the previous position to half way on to the next one (the ends at the first and last)
    [m], for positions increasing along the route."""
    s = np.asarray(position_m, dtype=float)
    mid = 0.5 * (s[1:] + s[:-1])
    return np.concatenate([s[:1], mid]), np.concatenate([mid, s[-1:]])


def route_with_share(route: Route, train: Train, profile: ShareProfile) -> Route:
    """``route`` with its electrification cut at the profile's breakpoints, each piece carrying the
    profile's share (parts the route leaves uncovered become sections at the train's nominal line
    voltage, which is what the core assumes there)."""
    if not profile.limited:
        return route
    nominal = train.electrical.line_voltage_v if train.electrical else 0.0
    pieces = split_spans(electrification_cover(route, nominal), profile.x_m[1:-1])
    mid = np.array([0.5 * (e.start_m + e.end_m) for e in pieces])
    shares = profile.at(mid)
    sections = tuple(
        dataclasses.replace(e, traction_share=float(w)) for e, w in zip(pieces, shares, strict=True)
    )
    return dataclasses.replace(route, electrification=sections)
