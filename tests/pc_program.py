"""A PC program of the tests' own, run as its own process against ``cnc-twin serve``: the jog of
examples/pc_jog.py (its planning, its JSON), streamed through the Python client library, and
misbehaving on request, as an outside program may (tests/test_serve.py).

    python tests/pc_program.py ATTACH CONFIG.json [--every-period] [--corrupt SEQ:BIT]
                               [--stop-after N] [--die-after N]

--every-period  never raise ALL_SENT nor WAKE_FREE: the card posts a status every period
--corrupt       flip bit BIT of record SEQ the first time it is written (after its CRC)
--stop-after    after answering N statuses, stop (SIGSTOP itself): no answer, no heartbeat
--die-after     after answering N statuses, die (SIGKILL itself)

Prints ``ended STATE FAULT`` (the card's end state) when the run is over.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "clients" / "python"))
sys.path.insert(0, str(ROOT / "examples"))

from cnct_client import Card, Streamer  # noqa: E402
from pc_jog import plan  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("attach", type=Path)
    parser.add_argument("config", type=Path)
    parser.add_argument("--every-period", action="store_true")
    parser.add_argument("--corrupt", default=None)
    parser.add_argument("--stop-after", type=int, default=None)
    parser.add_argument("--die-after", type=int, default=None)
    args = parser.parse_args()
    records, periods = plan(json.loads(args.config.read_text()))
    flipped = set()

    def corrupt(seq: int, data: bytes) -> bytes:
        want, bit = map(int, args.corrupt.split(":"))
        if seq != want or seq in flipped:
            return data
        flipped.add(seq)
        changed = bytearray(data)
        changed[bit // 8] ^= 1 << (bit % 8)
        return bytes(changed)

    answered = [0]

    def misbehave(_status: dict) -> None:
        if args.stop_after is not None and answered[0] == args.stop_after:
            os.kill(os.getpid(), signal.SIGSTOP)
        if args.die_after is not None and answered[0] == args.die_after:
            os.kill(os.getpid(), signal.SIGKILL)
        answered[0] += 1

    with Card(args.attach) as card:
        stream = Streamer(card, corrupt=corrupt if args.corrupt else None, solo=not args.every_period,
                          fifo_interrupt=not args.every_period)
        for record in records:
            stream.add(record)
        stream.complete = True
        card.attach(program_periods=periods)
        stream.run(on_status=misbehave)
        print("ended", *card.end_state(), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
