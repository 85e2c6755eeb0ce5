"""``python -m socialnav``: the ``socialnav`` command line (the same as ``python -m socialnav.cli``)."""

import sys

from socialnav.cli import main

if __name__ == "__main__":
    sys.exit(main())
