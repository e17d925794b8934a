"""The PC planner as its own OS process: plan, encode, stream records through the whiteboard.

``planner_main`` does one run's work; :func:`serve` runs one run after another in the process
that :mod:`cnc_twin.planner.launch` starts (``python -m cnc_twin.planner.process --serve``).
Per DSP status it writes as many records as fit (:mod:`cnc_twin.planner.stream`), bounded by

- the free FIFO space,
- the chunk size (the card takes 4 KB per mailbox interrupt),
- the look-ahead: motion queued ahead of execution (0 = no limit): what the card reports as
  queued (``queued_periods``, including the rest of the running move) plus what is in flight;
  the record right after the running one is always sent.

When the DSP reports more rejected records than before, the planner goes back to the DSP's
``expected_seq`` and sends from there again (go-back-N); the DSP flushed the FIFO when it
rejected, so the resent records are next in line.

Injected faults (scenario ``faults:``) act here, on the PC side
(:mod:`cnc_twin.planner.faults`).
"""

from __future__ import annotations

import os
import signal
import sys
import traceback
from multiprocessing.connection import Connection

from cnc_twin.core.errors import one_line
from cnc_twin.planner.faults import FaultSchedule
from cnc_twin.planner.job import PlannerJob
from cnc_twin.planner.stream import Feeder, Streamer
from cnc_twin.whiteboard import layout as L
from cnc_twin.whiteboard.block import Whiteboard
from cnc_twin.whiteboard.doorbell import Doorbell
from cnc_twin.whiteboard.ports import PcPort
from cnc_twin.whiteboard.status import DspState

PLAN_AHEAD_CHUNKS = 4
"""chunks planned beyond the first ones before the planner reports ready (the rest are planned
by its thread while the card runs)"""
FAILURE_BYTES = 400
"""the longest failure reason the planner reports [bytes]"""


def planner_main(shm_name: str, job: PlannerJob, wait_dsp: Connection | int, ring_dsp: Connection | int) -> None:
    """Process entry point: attach, plan, announce, then answer every DSP status until the end.

    ``wait_dsp`` / ``ring_dsp`` are the planner's ends of the mailbox doorbells.
    """
    # Ctrl-C reaches the whole process group; the DSP side decides how the run ends.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    wb = Whiteboard.attach(shm_name, L.Layout(job.layout_words))
    port = PcPort(wb, wait_dsp=Doorbell(wait_dsp), ring_dsp=Doorbell(ring_dsp))
    try:
        if job.replay is not None:  # a PC program's recorded stream: the same words, the same answers
            from cnc_twin.planner.replay import Replay

            feeder = streamer = Replay(job.replay)
            streamer.before_first_status(port)
        else:
            streamer = Streamer(chunk_words=job.chunk_words, lookahead_periods=job.lookahead_periods)
            feeder = Feeder(job, streamer)
        faults = FaultSchedule(job.faults)
        # The first chunks are planned before the card is told the planner is ready, as a PC fills
        # the card's buffer before cycle start: the run's clock does not wait for them. Lockstep
        # plans the same chunks as at the first status (the backlog rule sees the same counts).
        feeder.top_up()
        feeder.plan_ahead(PLAN_AHEAD_CHUNKS)
        port.announce(program_periods=feeder.program.estimated_periods)
        while True:
            status = port.wait_status()
            if status is None:
                break
            st = status[0]
            sim_time = float(st["sim_time"])
            faults.before_answer(sim_time)
            feeder.see(status)
            feeder.top_up()
            wb.plan_us[0] = min(int(feeder.plan_seconds * 1e6), 0xFFFFFFFF)
            wb.plan_blocks[0] = feeder.blocks
            port.begin()
            before = streamer.retransmitted
            streamer.answer(status, port, corrupt=faults.corrupter(sim_time))
            wb.records_sent[0] = streamer.next_index
            wb.retransmits[0] = wb.retransmits[0] + (streamer.retransmitted - before)
            port.set_all_sent(streamer.all_sent and faults.idle)
            # the card's FIFO-threshold interrupt: the next exchange once the next record fits
            # (not while scheduled faults need the status stream)
            port.set_wake(streamer.wake_free if job.fifo_interrupt and faults.idle else 0)
            port.end()
            port.set_state(L.PcState.STREAMING)
            if int(st["state"]) in (DspState.FINISHED, DspState.FAULT):
                break
        port.set_state(L.PcState.DONE)
    except BaseException:
        port.set_state(L.PcState.ERROR)
        traceback.print_exc(file=sys.stderr)
        raise
    finally:
        del port
        wb.close()


def serve(wait_fd: int, ring_fd: int) -> int:
    """Serve runs until EOF on stdin: read ``(shm name, job)`` (a 4-byte little-endian length,
    then the pickle), run it, write one status byte to the original stdout: 0 done, or 1 failed
    followed by the reason (2-byte little-endian length, then the exception's type and message in
    UTF-8, one line, at most :data:`FAILURE_BYTES`).
    A failed run ends the process (its traceback is on stderr). See :mod:`cnc_twin.planner.launch`."""
    import pickle
    import struct

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the group; the DSP side decides
    # The status bytes get a private descriptor; anything printed goes to stderr, not into them.
    status_fd = os.dup(1)
    os.dup2(2, 1)
    stdin = sys.stdin.buffer
    while True:
        header = stdin.read(4)
        if len(header) < 4:
            return 0
        payload = stdin.read(struct.unpack("<I", header)[0])
        shm_name, job = pickle.loads(payload)
        Doorbell(wait_fd).drain()  # rings left over from the last run
        try:
            planner_main(shm_name, job, wait_fd, ring_fd)
        except BaseException as exc:
            # the reason, for the run's metrics and the one-line error (the traceback is on stderr)
            reason = one_line(f"{type(exc).__name__}: {exc}").encode("utf-8", "replace")[:FAILURE_BYTES]
            os.write(status_fd, b"\x01" + len(reason).to_bytes(2, "little") + reason)
            return 1
        os.write(status_fd, b"\x00")


def main(argv: list[str] | None = None) -> int:
    """``python -m cnc_twin.planner.process --serve WAIT_FD RING_FD``: serve runs whose jobs come
    on stdin (:func:`serve`), started by :class:`cnc_twin.planner.launch.PlannerProcess`.

    Started as a plain subprocess (not multiprocessing's spawn), so the user's main script is
    never imported again in here: scripts need no ``if __name__ == "__main__"`` guard.
    """
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 3 or args[0] != "--serve":
        print("usage: python -m cnc_twin.planner.process --serve WAIT_FD RING_FD", file=sys.stderr)
        return 2
    return serve(int(args[1]), int(args[2]))


if __name__ == "__main__":
    code = main()
    # every run served: end without the interpreter's teardown (the twin's command waits for it)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
