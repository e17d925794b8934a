"""Injected card and machine faults (scenario ``faults:``), applied at interpolation-period boundaries.

The PC-side faults (planner stall, delay, kill, record bit flip) act in the planner process
(:class:`cnc_twin.planner.faults.FaultSchedule`). The rest act here, on the simulated hardware,
each from the first period starting at or after its ``at``:

==============  ===============================================================================
encoder_loss    the axis's encoder channel reads ``counts`` fewer from then on (missed edges)
encoder_noise   each reading gets a random whole offset in +-amplitude (seeded), for ``duration``
dac_stuck       the DAC output keeps the code it had; the card's writes no longer reach the drive
dac_dead        the DAC output is 0 V
torque_drop     the drive's force range is scaled by ``fraction`` (MuJoCo actuator forcerange)
force_spike     the load cell reads ``force`` N more for ``duration`` (at least one period)
force_offset    the load cell reads ``force`` N more from then on
collision       an obstacle box (a mocap body in the MJCF) moves into place
dsp_hang        the card's task stops for ``duration``: see :mod:`cnc_twin.run.twin` (watchdog)
==============  ===============================================================================

The card cannot tell a stuck channel from a good one: the trace's ``dac`` column keeps showing
the codes the card wrote.
"""

from __future__ import annotations

import math

import numpy as np

from cnc_twin.core.config import PLANNER_FAULTS, FaultInjection
from cnc_twin.dsp.servo import ServoTask
from cnc_twin.machine.plant import Plant

_NOISE_BLOCK = 4096


class EncoderNoise:
    """Seeded whole-count noise on one axis's encoder readings, +-``amplitude`` (a block of
    ``_NOISE_BLOCK`` draws, cycled): the next draw per servo tick."""

    __slots__ = ("axis", "_noise", "_i")

    def __init__(self, axis: int, amplitude: int, rng: np.random.Generator):
        self.axis = axis
        self._noise = rng.integers(-amplitude, amplitude + 1, size=_NOISE_BLOCK).tolist()
        self._i = 0

    def next(self) -> int:
        """This tick's offset [counts]."""
        self._i = (self._i + 1) % _NOISE_BLOCK
        return self._noise[self._i]


class FaultInjector:
    """The card- and machine-side faults of a run.

    Parameters
    ----------
    faults : the scenario's faults (PC-side ones are ignored here).
    servo, plant : what the faults act on.
    period, servo_period : interpolation and servo periods [s].
    seed : the scenario's seed (encoder noise).
    """

    def __init__(self, faults: tuple[FaultInjection, ...], *, servo: ServoTask, plant: Plant, period: float,
                 servo_period: float, seed: int):
        self.servo, self.plant = servo, plant
        self.period, self.servo_period = period, servo_period
        self.rng = np.random.default_rng(seed)
        self.obstacles = [f for f in faults if f.kind == "collision"]
        # (start period, end period or None, index, fault)
        self._events = sorted(
            ((self._start(f), self._end(f), i, f) for i, f in enumerate(faults) if f.kind not in PLANNER_FAULTS),
            key=lambda e: (e[0], e[2]))
        self._active: list[tuple[int, int, FaultInjection, object]] = []
        """windowed faults in force: (end period, index, fault, what to restore)"""
        self.hang_ticks = 0
        """servo ticks the card's task is still to miss (dsp_hang)"""
        self._lost = [0] * servo.n_axes
        """encoder edges each axis has missed (encoder_loss) [counts]"""
        self._noise: list[EncoderNoise] = []
        """the encoder noise in force"""
        self.next_period = self._next()
        """the next period at which anything starts or ends (the twin calls begin_period then)"""

    def _start(self, f: FaultInjection) -> int:
        return max(0, math.ceil(f.at / self.period - 1e-9))

    def _end(self, f: FaultInjection) -> int | None:
        if f.kind in ("encoder_noise", "force_spike") and f.duration > 0:
            return self._start(f) + max(1, math.ceil(f.duration / self.period - 1e-9))
        return None

    def _next(self) -> float:
        starts = [e[0] for e in self._events]
        ends = [a[0] for a in self._active]
        return min(starts + ends, default=math.inf)

    def begin_period(self, k: int) -> None:
        """Start and end what is due at period ``k``."""
        for entry in [a for a in self._active if a[0] <= k]:
            self._active.remove(entry)
            self._finish(*entry[1:])
        while self._events and self._events[0][0] <= k:
            _, end, index, fault = self._events.pop(0)
            restore = self._apply(index, fault)
            if end is not None:
                self._active.append((end, index, fault, restore))
        self.next_period = self._next()

    def _encoder_offsets(self) -> None:
        """The counts the faults add to each encoder reading now (lost edges, this tick's noise),
        into the servo's records: once when a loss starts, before every tick while noise is on."""
        offsets = [-lost for lost in self._lost]
        for noise in self._noise:
            offsets[noise.axis] += noise.next()
        self.servo.axes["encoder_fault"] = offsets

    def _noise_changed(self) -> None:
        self.servo.fault_hook = self._encoder_offsets if self._noise else None
        if not self._noise:
            self._encoder_offsets()

    def _apply(self, index: int, f: FaultInjection):
        servo, plant, axis = self.servo, self.plant, f.axis
        if f.kind == "encoder_loss":
            self._lost[axis] += int(f.value)
            self._noise_changed()
        elif f.kind == "encoder_noise":
            noise = EncoderNoise(axis, int(f.value), self.rng)
            self._noise.append(noise)
            self._noise_changed()
            return noise
        elif f.kind in ("dac_stuck", "dac_dead"):
            dac = servo.axes["dac"]
            dac["stuck_code"][axis] = dac["code"][axis] if f.kind == "dac_stuck" else 0
            dac["stuck"][axis] = 1
        elif f.kind == "torque_drop":
            plant.scale_force_limit(axis, f.value)
        elif f.kind in ("force_spike", "force_offset"):
            servo.force_fault += f.value
        elif f.kind == "collision":
            plant.place_obstacle(self.obstacles.index(f), f.position)
        elif f.kind == "dsp_hang":
            self.hang_ticks = max(1, round(f.duration / self.servo_period))
        else:  # pragma: no cover - the schema admits no other kind
            raise ValueError(f"unknown fault kind {f.kind!r}")
        return None

    def _finish(self, index: int, f: FaultInjection, restore) -> None:
        if f.kind == "encoder_noise":
            self._noise.remove(restore)
            self._noise_changed()
        elif f.kind == "force_spike":
            self.servo.force_fault -= f.value
