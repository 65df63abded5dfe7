"""``python -m bondid.fit``: see :mod:`bondid.fit.cli`."""

from __future__ import annotations

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
