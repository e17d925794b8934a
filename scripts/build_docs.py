"""Build the documentation site as CI does, and check it covers the package.

    python scripts/build_docs.py [--out docs/_build/html]

Sphinx with ``-W -n --keep-going``: every warning (a broken link, a reference that does not
resolve, a docstring docutils cannot read, a benchmark file the performance page cannot render)
fails the build, after all of them are listed. Then every module of the ``cnc_twin`` package
must have its page in the API reference. Exit 0 when both hold, 1 otherwise.
"""

from __future__ import annotations

import argparse
import pkgutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def package_modules() -> list[str]:
    """Every module and package under ``cnc_twin`` (``__main__`` left out: importing it runs the
    command line)."""
    import cnc_twin

    names = ["cnc_twin"]
    for info in pkgutil.walk_packages(cnc_twin.__path__, prefix="cnc_twin."):
        if not info.name.endswith("__main__"):
            names.append(info.name)
    return sorted(names)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "_build" / "html")
    args = parser.parse_args(argv)
    started = time.monotonic()
    build = subprocess.run([sys.executable, "-m", "sphinx", "-W", "-n", "--keep-going", "-q", "-b", "html",
                            str(ROOT / "docs"), str(args.out)], cwd=ROOT)
    if build.returncode != 0:
        print(f"docs: the build failed (exit {build.returncode}): its warnings are above", file=sys.stderr)
        return 1
    missing = [name for name in package_modules() if not (args.out / "api" / f"{name}.html").is_file()]
    if missing:
        print(f"docs: no API reference page for {len(missing)} module(s): {', '.join(missing)}", file=sys.stderr)
        return 1
    print(f"docs: built without a warning in {time.monotonic() - started:.0f} s, "
          f"an API page for each of the {len(package_modules())} modules: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
