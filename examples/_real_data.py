"""Where the gallery examples on real robot logs look for them (not an example).

The logs are not part of the package (their licences do not allow it):
``$GPCD_REAL_DATA/<name>`` when that variable is set, else
``../shared/data/real/<name>`` next to the repository.
"""

import os
from pathlib import Path

HERE = Path(__file__).resolve().parent


def find_data(name):
    """The folder of data set ``name``, or None when it is absent."""
    if os.environ.get("GPCD_REAL_DATA"):
        root = Path(os.environ["GPCD_REAL_DATA"]).expanduser()
    else:
        root = HERE.parent.parent / "shared" / "data" / "real"
    return root / name if (root / name).is_dir() else None
