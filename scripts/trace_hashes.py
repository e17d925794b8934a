"""Print a SHA-256 of every bundled scenario's trace, to show a change left the runs bit for bit.

    python scripts/trace_hashes.py [SCENARIO.yaml ...] [--json OUT] [--skip PREFIX ...]

Each scenario runs once in lockstep, in this process, with the compiled kernels (the default
twin). The hash covers every trace column (``Trace.columns()``: name, dtype, shape and bytes,
in column order) and, for polishing runs, the removal map. Run it before and after a
refactoring and compare the lines; a change that should leave behaviour alone must leave them
equal. ``--skip tip_ --skip pivot_`` leaves out the columns whose names start so (a change
that adds columns: the hashes of the others, before and after).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

from cnc_twin import load_scenario, run_scenario
from cnc_twin.scenario.resources import scenarios_dir
def trace_hash(result, skip: tuple[str, ...] = ()) -> str:
    """SHA-256 over the trace's columns but those starting with a ``skip`` prefix (and the
    removal map, if any), hex."""
    digest = hashlib.sha256()
    for name, column in result.trace.columns().items():
        if name.startswith(skip):
            continue
        column = np.ascontiguousarray(column)
        digest.update(f"{name}:{column.dtype.str}:{column.shape}".encode())
        digest.update(column.tobytes())
    if result.removal is not None:
        depth = np.ascontiguousarray(result.removal.depth)
        digest.update(depth.tobytes())
    return digest.hexdigest()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*", type=Path)
    parser.add_argument("--json", type=Path)
    parser.add_argument("--skip", action="append", default=[], metavar="PREFIX")
    args = parser.parse_args(argv)
    files = args.scenarios or sorted(scenarios_dir().glob("*.yaml"))
    hashes = {}
    for file in files:
        result = run_scenario(load_scenario(file))
        hashes[file.stem] = {"sha256": trace_hash(result, tuple(args.skip)), "ticks": len(result.trace), "status": result.status}
        print(f"{file.stem:22s} {hashes[file.stem]['sha256']}  {len(result.trace)} ticks  {result.status}",
              flush=True)
    if args.json:
        args.json.write_text(json.dumps(hashes, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
