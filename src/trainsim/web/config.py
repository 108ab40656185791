"""Limits of the web application: every store and every request is bounded."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class WebSettings:
    """Bounds of the web application (all in plain units named in the field).

    Attributes:
        max_sessions: browser sessions kept at once; past that the least recently used session
            without a live drive is dropped.
        session_ttl_s: a session unused for this long is dropped [s].
        max_runs_per_session: runs (and recorded drives) kept per session; the oldest goes first.
        max_total_trace_points: trace points kept over all sessions (bounds memory: a point is
            about 200 bytes); past that the oldest runs of any session are dropped.
        max_body_bytes: largest request body (JSON or uploaded file) [bytes].
        max_list_items: longest list in a train or route (table rows, effort-table points).
        max_route_length_m: longest route accepted [m].
        max_grid_points: largest route length / integration step of a run; bounds a run's
            time and memory.
        max_plot_points: points sent per run for plotting (the CSV has them all).
        max_drives: live drives over all sessions at once.
        max_drive_wall_s: a live drive ends after this much wall-clock time [s].
        drive_tick_s: wall-clock period of the live drive's steps and state messages [s].
    """

    max_sessions: int = 200
    session_ttl_s: float = 3600.0
    max_runs_per_session: int = 8
    max_total_trace_points: int = 2_000_000
    max_body_bytes: int = 2 * 1024 * 1024
    max_list_items: int = 5000
    max_route_length_m: float = 2_000_000.0
    max_grid_points: int = 400_000
    max_plot_points: int = 4000
    max_drives: int = 32
    max_drive_wall_s: float = 4 * 3600.0
    drive_tick_s: float = 0.1
