"""``python -m trainsim``: the ``trainsim`` command."""

from trainsim.cli.app import main

main()
