"""``python -m robocal``: the same as the ``robocal`` command."""

import sys

from .cli import main

if __name__ == "__main__":  # guarded so that test collection can import this module
    sys.exit(main())
