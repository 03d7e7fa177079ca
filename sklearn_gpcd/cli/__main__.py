"""``python -m sklearn_gpcd.cli``: the ``gpcd`` command."""

import sys

from . import main

if __name__ == "__main__":
    sys.exit(main())
