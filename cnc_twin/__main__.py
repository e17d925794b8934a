"""``python -m cnc_twin`` is the same as the ``cnc-twin`` command."""

from cnc_twin.entry import main

raise SystemExit(main())
