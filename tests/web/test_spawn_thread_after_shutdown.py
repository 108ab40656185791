"""A spawn thread whose server stopped while it worked ends quietly (the loop it would hand its result
to is closed; nobody awaits it). CI once printed "Event loop is closed" from such a thread."""

from __future__ import annotations

import asyncio
import threading

from trainsim.web.workers import in_daemon_thread


def test_work_finishing_after_the_loop_closed_raises_nothing() -> None:
    release = threading.Event()
    finished = threading.Event()
    errors: list[BaseException] = []
    previous = threading.excepthook
    threading.excepthook = lambda args: errors.append(args.exc_value)
    try:

        def slow() -> int:
            release.wait(5.0)
            finished.set()
            return 1

        async def start() -> asyncio.Future:
            return in_daemon_thread(slow)

        loop = asyncio.new_event_loop()
        loop.run_until_complete(start())
        loop.close()
        release.set()
        assert finished.wait(5.0)
        for t in threading.enumerate():
            if t.name == "trainsim-web-spawn":
                t.join(5.0)
    finally:
        threading.excepthook = previous
    assert errors == []
