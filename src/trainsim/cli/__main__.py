"""``python -m trainsim.cli``: the ``trainsim`` command."""

from trainsim.cli.app import main

main()
