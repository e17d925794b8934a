"""Whiteboard speed figures between two real processes, through the real ports.

``exchange_round_trip``: the DSP posts a status and waits for the PC's acknowledgement, over and
over with no servo work between (the full hand-over: mailbox, HOLD/HOLDA, status copy, ack).
Figures: median and p99 of post -> acknowledgement seen [us]. The PC side is the twin's own port
with the inherited pipe doorbells, spinning on the mailbox first or not (``spin``);
``external_round_trip`` measures the same with an outside program as the PC side, through an
attach folder's named-pipe doorbells (``cnc-twin serve``'s; benchmarks/pc_echo.py and .c).

``stream_throughput``: the PC streams pre-encoded records as fast as the FIFO and the chunk size
allow; the DSP copies each exchange's records out of the ring, hands the bus back, then checks
(CRC) and decodes every one, until end of program; PC writing and DSP decoding overlap, as on
the card. Figure: record
bytes moved and verified per second [MB/s], compared with the 132 MB/s burst rate of the
32-bit / 33 MHz PCI bus the card's bridge chip runs on.
"""

from __future__ import annotations

import multiprocessing
import time
from typing import Any

import numpy as np

from cnc_twin.motion.trapezoid import Trapezoid
from cnc_twin.whiteboard.block import Whiteboard
from cnc_twin.whiteboard.codec import decode, encode
from cnc_twin.whiteboard.doorbell import SPIN_POLLS, Doorbell, Doorbells
from cnc_twin.whiteboard.layout import Layout, PcState
from cnc_twin.whiteboard.ports import DspPort, PcPort, signal_shutdown
from cnc_twin.whiteboard.records import DataBlock, EndOfProgram, Move
from cnc_twin.whiteboard.status import STATUS_DTYPE

PCI_BURST_MB_S = 132.0


def _echo(shm_name: str, wait_dsp, ring_dsp, words: int, spin: bool = True) -> None:
    """PC side of the round-trip benchmark: acknowledge every status, write nothing."""
    wb = Whiteboard.attach(shm_name, Layout(words))
    port = PcPort(wb, wait_dsp=Doorbell(wait_dsp), ring_dsp=Doorbell(ring_dsp), spin_polls=SPIN_POLLS if spin else 0)
    try:
        port.announce(program_periods=0)
        while port.wait_status() is not None:
            port.begin()
            port.end()
    finally:
        del port
        wb.close()


def _source(shm_name: str, wait_dsp, ring_dsp, words: int, chunk_words: int, kind: str, count: int) -> None:
    """PC side of the throughput benchmark: stream ``count`` records, then end of program."""
    wb = Whiteboard.attach(shm_name, Layout(words))
    port = PcPort(wb, wait_dsp=Doorbell(wait_dsp), ring_dsp=Doorbell(ring_dsp), spin_polls=SPIN_POLLS)
    try:
        if kind == "block":
            payload = np.arange(chunk_words - 6, dtype="<u2")
            records = [DataBlock(words=payload)] * count
        else:
            move = Move(end=(0.1, 0.2, -0.1, 0.3, -0.3, 1.0), profile=Trapezoid(0.1, 0.2, 3.0, 30.0), periods=400)
            records = [move] * count
        encoded = [encode(r, seq) for seq, r in enumerate(records + [EndOfProgram()], start=1)]
        port.announce(program_periods=0)
        i = 0
        while port.wait_status() is not None:
            port.begin()
            budget, free = chunk_words, port.fifo.free()
            while i < len(encoded) and len(encoded[i]) <= min(budget, free):
                port.fifo.write(encoded[i])
                budget -= len(encoded[i])
                free -= len(encoded[i])
                i += 1
            port.end()
        port.set_state(PcState.DONE)
    finally:
        del port
        wb.close()


def _with_pc(target, args: tuple, words: int, body) -> Any:
    ctx = multiprocessing.get_context("spawn")
    wb = Whiteboard.create(Layout(words))
    bells = Doorbells(ctx)
    proc = ctx.Process(target=target, args=(wb.name, *bells.pc_ends(), *args), daemon=True)
    proc.start()
    try:
        port = DspPort(wb, lockstep=True, planner_alive=proc.is_alive, heartbeat_timeout=5.0,
                       ring_pc=bells.ring_pc, wait_pc=bells.wait_pc)
        port.wait_ready(60.0)
        return body(port)
    finally:
        signal_shutdown(wb, bells.ring_pc)
        proc.join(5.0)
        if proc.is_alive():
            proc.kill()
            proc.join()
        port = None
        bells.close()
        wb.close()


def _round_trips(n: int):
    """The DSP side of ``n`` round trips: figures [us] from a ready port."""
    status = np.zeros(1, dtype=STATUS_DTYPE)

    def body(port: DspPort) -> dict[str, Any]:
        rt = np.empty(n, dtype=np.int64)
        for k in range(n + 1):
            port.acquire(k)
            seen = time.perf_counter_ns()
            if k:
                rt[k - 1] = seen - port.post_ns
            if k == n:
                break
            port.pop_records()
            port.publish(status, k)
        us = rt / 1e3
        return {"exchanges": n, "median_us": float(np.median(us)), "p99_us": float(np.percentile(us, 99)),
                "min_us": float(us.min())}

    return body


def exchange_round_trip(n: int = 20000, *, words: int = 8192, spin: bool = True) -> dict[str, Any]:
    """Round trips DSP post -> PC acknowledgement seen, between two processes [us]; the PC's port
    spins on the mailbox before it sleeps on its doorbell, or (``spin=False``) sleeps at once."""
    return _with_pc(_echo, (words, spin), words, _round_trips(n))


def external_round_trip(command: list[str], n: int = 20000, *, words: int = 8192) -> dict[str, Any]:
    """Round trips as :func:`exchange_round_trip`, the PC side the outside program ``command``
    given the attach folder as its last argument (an echo: acknowledge every status)."""
    import subprocess

    from cnc_twin.whiteboard.attach_point import AttachPoint

    wb = Whiteboard.create(Layout(words))
    point = AttachPoint(wb.name)
    proc = subprocess.Popen([*command, str(point.folder)])
    try:
        port = DspPort(wb, lockstep=True, planner_alive=lambda: proc.poll() is None and not point.pc_gone(),
                       heartbeat_timeout=5.0, ring_pc=point.ring_pc, wait_pc=point.wait_pc)
        port.wait_ready(60.0)
        return _round_trips(n)(port)
    finally:
        signal_shutdown(wb, point.ring_pc)
        try:
            proc.wait(5.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        port = None
        point.close()
        wb.close()


def stream_throughput(*, kind: str = "block", count: int = 4000, words: int = 8192, chunk_bytes: int = 4096) -> dict[str, Any]:
    """Stream ``count`` records (4 KB data blocks or Move records) PC -> DSP; MB/s verified."""
    chunk_words = chunk_bytes // 2
    status = np.zeros(1, dtype=STATUS_DTYPE)

    def body(port: DspPort) -> dict[str, Any]:
        moved = 0
        records = 0
        start = time.perf_counter()
        k = 0
        done = False
        while not done:
            port.acquire(k)
            raws = port.pop_records()   # copied out of the ring: the PC may refill it at once
            port.publish(status, k)
            for raw in raws:             # ... while the DSP checks and decodes what it took
                _, record = decode(raw)
                moved += 2 * len(raw)
                records += 1
                done = isinstance(record, EndOfProgram)
            k += 1
        seconds = time.perf_counter() - start
        return {"kind": kind, "records": records, "bytes": moved, "seconds": seconds, "exchanges": k,
                "mb_per_s": moved / seconds / 1e6, "pci_burst_mb_per_s": PCI_BURST_MB_S,
                "ratio_to_pci": moved / seconds / 1e6 / PCI_BURST_MB_S}

    return _with_pc(_source, (words, chunk_words, kind, count), words, body)


def whiteboard_figures() -> dict[str, float]:
    """``cnc-twin bench``'s whiteboard figures: the exchange's round trip (median, p99 [us]) and
    the streaming throughput of 4 KB blocks and of move records [MB/s], with the PCI burst."""
    rt = exchange_round_trip()
    block = stream_throughput(kind="block")
    move = stream_throughput(kind="move", count=20000)
    return {
        "exchange_round_trip_median_us": rt["median_us"],
        "exchange_round_trip_p99_us": rt["p99_us"],
        "stream_4k_blocks_mb_per_s": block["mb_per_s"],
        "stream_move_records_mb_per_s": move["mb_per_s"],
        "pci_burst_mb_per_s": block["pci_burst_mb_per_s"],
    }
