"""The PC side of the external round-trip benchmark, in Python (clients/python): attach, then
acknowledge every status, writing nothing, until the run is over.

    python benchmarks/pc_echo.py [SPIN_POLLS] ATTACH_FOLDER
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "clients" / "python"))

from cnct_client import Card  # noqa: E402

with Card(sys.argv[-1], spin_polls=int(sys.argv[1]) if len(sys.argv) > 2 else 0) as card:
    card.attach()
    while card.wait_status() is not None:
        card.begin()
        card.end()
