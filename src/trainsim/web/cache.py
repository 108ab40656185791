"""Results of identical runs computed once: a small LRU cache of run results, with requests in flight
shared (single flight).

A run is identified by its train and route (the hash of their validated specs), run settings,
strategy and parameters; the core is deterministic, so the same key gives the same result. The
page repeats runs often (auto re-run after an edit that changed nothing, several users on the
same example); those cost one lookup instead of a run. Bounded: ``max_entries`` results (each at
most ``max_points`` trace points are kept; larger ones are not cached).
"""

from __future__ import annotations

import asyncio
import hashlib
import json
from collections import OrderedDict
from collections.abc import Awaitable, Callable
from typing import Any

from trainsim.web.convert import spec_dict
from trainsim.web.sessions import Loaded

__all__ = ["RunCache", "identity"]


def identity(loaded: Loaded) -> str:
    """A hash of a loaded train's or route's validated spec (computed once per object)."""
    key = getattr(loaded, "key", None)
    if not key:
        text = json.dumps(spec_dict(loaded.spec), sort_keys=True, default=str)
        key = hashlib.sha256(text.encode()).hexdigest()
        loaded.key = key
    return key


class RunCache:
    """LRU cache of ``key -> (RunResult, answer body)`` with shared in-flight computations."""

    def __init__(self, max_entries: int = 32, max_points: int = 100_000) -> None:
        self.max_entries = max_entries
        self.max_points = max_points
        self._done: OrderedDict[str, tuple[Any, bytes]] = OrderedDict()
        self._running: dict[str, asyncio.Future] = {}
        self.hits = 0
        self.misses = 0

    def __len__(self) -> int:
        return len(self._done)

    async def get(self, key: str, compute: Callable[[], Awaitable[tuple[Any, bytes]]]) -> tuple[Any, bytes]:
        """The cached value of ``key``, the value of the same computation in flight, or
        ``await compute()`` (cached when it succeeds; errors are never cached)."""
        found = self._done.get(key)
        if found is not None:
            self._done.move_to_end(key)
            self.hits += 1
            return found
        running = self._running.get(key)
        if running is not None:
            self.hits += 1
            return await asyncio.shield(running)
        self.misses += 1
        future: asyncio.Future = asyncio.get_running_loop().create_future()
        self._running[key] = future
        try:
            value = await compute()
        except BaseException as exc:
            future.set_exception(exc)
            future.exception()  # retrieved: no "never retrieved" warning when nobody else waits
            raise
        finally:
            self._running.pop(key, None)
        future.set_result(value)
        result = value[0]
        if len(getattr(result, "trace", ())) <= self.max_points:
            self._done[key] = value
            while len(self._done) > self.max_entries:
                self._done.popitem(last=False)
        return value
