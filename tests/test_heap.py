"""What a run starts with (:func:`cnc_twin.core.heap.return_freed_memory`): garbage held in
reference cycles (a long program's reading leaves some, holding its text) is collected and its
memory given back to the system before the run, not late in it."""

from __future__ import annotations

import gc

import numpy as np

from cnc_twin.core.heap import resident_bytes, return_freed_memory


class _Cycle:
    def __init__(self, payload):
        self.payload, self.me = payload, self


def test_memory_held_by_a_dropped_cycle_is_given_back():
    gc.disable()  # the collector must not find the cycle by itself meanwhile
    try:
        return_freed_memory()
        before = resident_bytes()
        held = _Cycle(np.ones(50_000_000 // 8))  # 50 MB, touched
        del held
        assert resident_bytes() > before + 40e6  # a cycle: not freed when dropped
        return_freed_memory()
        assert resident_bytes() < before + 10e6
    finally:
        gc.enable()
