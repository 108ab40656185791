"""``python -m trainsim.batch STUDY.yaml [options]``: the ``trainsim batch`` command on its own."""

from trainsim.cli_batch import main

if __name__ == "__main__":
    main()
