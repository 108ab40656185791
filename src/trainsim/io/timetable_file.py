"""The timetable file (``schema: trainsim/timetable``, docs/OPTIMIZATION.md): read within bounds.

The file is parsed once by :mod:`trainsim.io.documents` (size, nesting depth and YAML aliases
bounded, duplicate keys refused), then checked and turned into a
:class:`~trainsim.model.timetable.Timetable` by :func:`trainsim.optimize.timetable.timetable_from_dict`.
Reading lives here, not in optimize, because optimize is below io in the layers (docs/DESIGN.md).
"""

from __future__ import annotations

from pathlib import Path

from trainsim.io.documents import read_yaml
from trainsim.model.timetable import Timetable
from trainsim.optimize.timetable import timetable_from_dict

__all__ = ["read_timetable_yaml"]


def read_timetable_yaml(path: str | Path, n_sections: int | None = None) -> Timetable:
    """Read a ``schema: trainsim/timetable`` file; ``n_sections`` (if given) is the number of sections
    between the route's stops, which a per-section timetable must match.

    Raises:
        InputError: naming the file, the line or field, the value and what is allowed.
    """
    return timetable_from_dict(read_yaml(path), str(path), n_sections)
