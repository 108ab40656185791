"""``python -m trainsim.batch STUDY.yaml [options]``: the same as ``trainsim batch``."""

import sys

from trainsim.cli.app import main

sys.argv[1:1] = ["batch"]
main()
