"""``python -m navsim.cli``: the ``navsim`` command."""

import sys

from .entry import main

if __name__ == "__main__":
    sys.exit(main())
