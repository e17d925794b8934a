"""Fetch and unpack LinuxCNC's G-code interpreter, the oracle the G-code reader is checked against.

    python scripts/fetch_linuxcnc_oracle.py [--dest .oracle/linuxcnc]

Debian 12 packages the interpreter (``linuxcnc-uspace``, with the boost.python library it links);
``apt-get download`` fetches the two .deb files from the configured Debian mirror without root,
and ``dpkg -x`` unpacks them into ``--dest``: no install, no services. What the tests use:

- ``usr/bin/rs274``: the stand-alone interpreter, ``rs274 -g -t tool.tbl FILE`` prints the
  canonical machine calls a program makes;
- ``usr/share/linuxcnc/ncfiles/``: the example programs LinuxCNC ships.

Run the interpreter with ``LD_LIBRARY_PATH=<dest>/usr/lib:<dest>/usr/lib/x86_64-linux-gnu``
(``tests/oracle.py`` does). The folder is left alone if it already holds ``usr/bin/rs274``.
LinuxCNC is GPL-2.0 software; it is only run by the tests, never bundled or imported.
Exit codes: 0 ready, 1 the download or unpacking failed (the reason on one line).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

PACKAGES = ("linuxcnc-uspace", "libboost-python1.74.0")
DEFAULT_DEST = Path(__file__).resolve().parents[1] / ".oracle" / "linuxcnc"


def fetch(dest: Path) -> Path:
    """Unpack the oracle into ``dest`` (unless it is there already); the rs274 binary's path."""
    rs274 = dest / "usr" / "bin" / "rs274"
    if rs274.is_file():
        return rs274
    for tool in ("apt-get", "dpkg"):
        if shutil.which(tool) is None:
            raise RuntimeError(f"{tool} not found: the oracle comes from Debian packages (Debian 12)")
    with tempfile.TemporaryDirectory() as folder:
        got = subprocess.run(["apt-get", "download", *PACKAGES], cwd=folder, capture_output=True, text=True)
        debs = sorted(Path(folder).glob("*.deb"))
        if got.returncode != 0 or len(debs) != len(PACKAGES):
            last = (got.stderr.strip().splitlines() or ["no output"])[-1]
            raise RuntimeError(f"apt-get download {' '.join(PACKAGES)} failed: {last}")
        staging = dest.with_name(dest.name + ".partial")
        shutil.rmtree(staging, ignore_errors=True)
        staging.mkdir(parents=True)
        for deb in debs:
            subprocess.run(["dpkg", "-x", str(deb), str(staging)], check=True, capture_output=True)
        shutil.rmtree(dest, ignore_errors=True)
        staging.rename(dest)  # whole or not at all
    if not rs274.is_file():
        raise RuntimeError(f"the packages unpacked, but {rs274} is not in them")
    return rs274


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dest", type=Path, default=DEFAULT_DEST, help="folder to unpack into")
    args = parser.parse_args(argv)
    try:
        rs274 = fetch(args.dest)
    except (RuntimeError, subprocess.CalledProcessError, OSError) as exc:
        print(f"error: the LinuxCNC oracle is not available: {exc}", file=sys.stderr)
        return 1
    print(f"LinuxCNC oracle ready: {rs274}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
