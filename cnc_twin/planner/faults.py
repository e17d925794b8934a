"""The PC-side injected faults (scenario ``faults:``): a stall (no answer and no heartbeat for a
while), a delay on every answer for a time window, a kill (the process dies as with SIGKILL), and
a bit flip in one record after its CRC was computed."""

from __future__ import annotations

import os
import signal
import time

import numpy as np

from cnc_twin.core.config import FaultInjection


class FaultSchedule:
    """The PC-side injected faults, each triggered by the simulated time of a status."""

    def __init__(self, faults: tuple[FaultInjection, ...]):
        self.faults = list(faults)
        self._fired: set[int] = set()

    def before_answer(self, sim_time: float) -> None:
        """Stall, delay or die, as scheduled for this status's time."""
        for i, f in enumerate(self.faults):
            if f.kind == "planner_kill" and sim_time >= f.at:
                os.kill(os.getpid(), signal.SIGKILL)
            if f.kind == "planner_stall" and sim_time >= f.at and i not in self._fired:
                self._fired.add(i)
                time.sleep(f.duration)
            if f.kind == "planner_delay" and sim_time >= f.at:
                since = sim_time - f.at
                if (since % f.every if f.every > 0 else since) < f.duration:
                    time.sleep(f.delay)

    @property
    def idle(self) -> bool:
        """Nothing scheduled is still to happen (faults need the status stream to keep going)."""
        return len(self._fired) == len(self.faults) and not any(
            f.kind in ("planner_kill", "planner_delay") for f in self.faults)

    def corrupter(self, sim_time: float):
        """A function flipping the scheduled bit in the next record, or None."""
        for i, f in enumerate(self.faults):
            if f.kind == "record_bitflip" and sim_time >= f.at and i not in self._fired:
                def flip(words: np.ndarray, i=i, bit=f.bit) -> np.ndarray:
                    self._fired.add(i)
                    out = words.copy()
                    b = bit % (16 * len(out))
                    out[b // 16] ^= np.uint16(1 << (b % 16))
                    return out
                return flip
        return None

