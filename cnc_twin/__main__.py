"""``python -m cnc_twin`` is the same as the ``cnc-twin`` command."""

from cnc_twin.entry import main

if __name__ == "__main__":  # imported (e.g. by the docs' API reference), it runs nothing
    raise SystemExit(main())
