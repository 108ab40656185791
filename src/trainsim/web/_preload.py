"""Imported once by the worker pool's fork server: trainsim loaded and its kernels compiled, so that
every worker forked from it starts warm. The server process never imports this module."""

from trainsim.web import jobs

jobs.warm()
