"""``python -m robofleet``: the same command line as the ``robofleet`` script."""

from robofleet.cli.main import main

if __name__ == "__main__":
    main()
