"""The exchange's round trip with your own PC program as the PC side (``cnc-twin serve``'s attach
folder, named-pipe doorbells) beside the twin's own planner port (inherited pipes), in one run:

    python -m pytest benchmarks/test_bench_pc_clients.py --benchmark-only -s -n0

Each: 20 000 exchanges, the DSP posting a status and waiting for the acknowledgement with no servo
work between; median and p99 of post -> acknowledgement seen [us]. "sleeps" = the PC sleeps on
its doorbell at once (the clients' default, and the twin's planner's in a run); "spins" = it polls
the mailbox 200 times first (the twin's benchmark figure in the README). docs/pc-software.md
quotes a run of it.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

from cnc_twin.studies.bench_whiteboard import exchange_round_trip, external_round_trip

HERE = Path(__file__).resolve().parent
SPIN = "200"


def test_round_trips_of_the_pc_sides(benchmark, tmp_path):
    compiler = shutil.which("cc") or shutil.which("gcc")
    assert compiler is not None, "no C compiler (cc): the C client's round trip cannot be measured"
    echo = tmp_path / "pc_echo"
    subprocess.run([compiler, "-O2", "-std=c11", f"-I{HERE.parent / 'clients' / 'c'}", HERE / "pc_echo.c",
                    HERE.parent / "clients" / "c" / "cnct_client.c", "-o", echo], check=True)
    python_echo = [sys.executable, str(HERE / "pc_echo.py")]

    def measure() -> dict:
        return {
            "twin's port, inherited pipes, spins": exchange_round_trip(spin=True),
            "twin's port, inherited pipes, sleeps": exchange_round_trip(spin=False),
            "Python client, attach folder, spins": external_round_trip([*python_echo, SPIN]),
            "Python client, attach folder, sleeps": external_round_trip(python_echo),
            "C client, attach folder, spins": external_round_trip([str(echo), SPIN]),
            "C client, attach folder, sleeps": external_round_trip([str(echo)]),
        }

    figures = benchmark.pedantic(measure, rounds=1)
    for name, row in figures.items():
        print(f"\n{name:40s} median {row['median_us']:7.1f} us   p99 {row['p99_us']:7.1f} us")
    benchmark.extra_info.update(figures)
