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
        max_depth: deepest nesting of mappings and lists in a document (JSON body or file).
        max_document_nodes: values in one document.
        max_string_chars: longest text value [characters].
        max_number_magnitude: largest absolute value of any number in a document.
        max_vehicles: vehicles in a train (formation counts summed).
        max_operation_trains: trains of an uploaded operation file (``repeat`` counts summed); bounds
            the run's time and the train graph's size.
        max_upload_files: files in an uploaded zip (an operation's or a scenario's folder).
        workers: worker processes that validate, read uploads and run (0: in the server process,
            without time or memory limits; for tests and debugging only).
        job_time_limit_s: wall-clock limit of one request's work in a worker [s]; past it the
            worker is stopped and the request gets 422.
        job_memory_limit_bytes: memory a worker may take on top of what it holds when it starts
            [bytes]; past it the request gets 422.
        start_timeout_s: longest a request waits for the worker processes to start [s]; the first
            start after an install compiles trainsim's kernels (minutes); past it the answer is 503.
        drive_hosts: processes that host the live drives (0: in the server process).
        max_queued_jobs: requests waiting for a worker; past that the answer is 503.
        max_jobs_per_session: requests of one session in the workers at once; past that 429.
        session_burst: new sessions one client (IP address) may make at once; past that it gets
            429 with ``Retry-After`` until its allowance refills.
        sessions_per_minute: rate at which a client's allowance of new sessions refills [1/min].
        max_rate_clients: clients whose allowance is remembered (the least recently seen is
            forgotten first; bounds memory under a flood from many addresses).
        allowed_hosts: values the ``Host`` header may have (without the port); other hosts get 400
            (protects against DNS rebinding). ``*`` allows any.
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
    max_depth: int = 24
    max_document_nodes: int = 200_000
    max_string_chars: int = 10_000
    max_number_magnitude: float = 1e9
    max_vehicles: int = 1000
    max_operation_trains: int = 200
    max_upload_files: int = 64
    workers: int = 2
    job_time_limit_s: float = 30.0
    job_memory_limit_bytes: int = 1024 * 1024 * 1024
    drive_hosts: int = 2
    start_timeout_s: float = 600.0
    max_queued_jobs: int = 64
    max_jobs_per_session: int = 2
    session_burst: int = 120
    sessions_per_minute: float = 120.0
    max_rate_clients: int = 10_000
    allowed_hosts: tuple[str, ...] = ("127.0.0.1", "localhost", "::1", "testserver")
