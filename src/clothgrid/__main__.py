"""``python -m clothgrid``: the command line, see :mod:`clothgrid.cli`."""

from __future__ import annotations

import sys

from .cli import console_main

if __name__ == "__main__":
    sys.exit(console_main())
