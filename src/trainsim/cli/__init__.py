"""The ``trainsim`` command line: one module per command group over the public API.

:mod:`trainsim.cli.app` holds the table of commands; :mod:`trainsim.cli.context` what they share
(exit codes, error reporting, console, scenario loading).
"""

from trainsim.cli.app import COMMANDS, app, main

__all__ = ["COMMANDS", "app", "main"]
