"""``python -m signorini``: the command line (:mod:`signorini.io.entry`).

The entry point sits above every layer of the package (tests/test_layout.py).
"""

import sys

from .io.entry import main

if __name__ == "__main__":
    sys.exit(main())
