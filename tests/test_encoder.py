"""QEP: quantisation exact to one count; 16-bit wrap extended to 32 bits in both directions."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from cnc_twin.dsp.encoder import extend_counter, new_encoder, qep_sample, wrap_int32

CPU = 1e6  # 1 um per count, as X/Y/Z


@given(st.floats(min_value=-0.032, max_value=0.032, allow_nan=False))
def test_quantisation_is_floor_of_position_exact_to_one_count(position):
    # One sample from power-on may move at most 2^15 - 1 counts (32 mm here): beyond that a
    # single 16-bit reading is ambiguous, on the real QEP too. Longer travel: see the wrap tests.
    enc = new_encoder(CPU)
    counts = qep_sample(enc, position, 0)
    assert counts == math.floor(position * CPU)
    assert 0 <= position * CPU - counts <= 1.0


def test_counts_are_relative_to_power_on_position():
    enc = new_encoder(CPU, position_at_power_on=0.0123456)
    assert qep_sample(enc, 0.0123456, 0) == 0
    assert qep_sample(enc, 0.0123456 + 10e-6, 0) == 10


def test_an_injected_offset_changes_the_reading_not_the_count():
    enc = new_encoder(CPU)
    assert qep_sample(enc, 10e-6, -3) == 7 and enc["position32"] == 10
    assert qep_sample(enc, 10e-6, 0) == 10


@pytest.mark.parametrize("direction", [+1, -1])
def test_wrap_at_16_bit_boundary_extends_to_32_bits(direction):
    """Travel 200 mm (200000 counts, three 16-bit wraps) in 50 um steps each way."""
    enc = new_encoder(CPU)
    crossings = 0
    last16 = 0
    for k in range(1, 4001):
        position = direction * k * 50e-6
        counts = qep_sample(enc, position, 0)
        assert counts == math.floor(position * CPU)  # exact, also across every 16-bit wrap
        assert abs(counts - position * CPU) <= 1.0
        assert 0 <= enc["counter16"] <= 0xFFFF
        crossings += abs(enc["counter16"] - last16) > 0x8000
        last16 = enc["counter16"]
    assert crossings == (3 if direction > 0 else 4)  # going down, 0 -> 65535 is the first wrap
    assert abs(enc["position32"] - direction * 200000) <= 1


def test_wrap_exactly_across_boundaries():
    # 32767 -> 32768 (no wrap in hardware, signed boundary), 65535 -> 0 (wrap up), 0 -> 65535 (down)
    assert extend_counter(32767, 32767, 32768) == 32768
    assert extend_counter(65535, 65535, 0) == 65536
    assert extend_counter(0, 0, 65535) == -1
    assert extend_counter(-65536, 0, 65535) == -65537


@given(st.integers(min_value=-(2**31), max_value=2**31 - 1), st.integers(min_value=-32767, max_value=32767))
def test_extension_recovers_any_step_below_half_range(start, step):
    last16 = start % 65536
    new16 = (start + step) % 65536
    assert extend_counter(start, last16, new16) == wrap_int32(start + step)


def test_32_bit_position_wraps_twos_complement():
    assert wrap_int32(2**31) == -(2**31)
    assert wrap_int32(-(2**31) - 1) == 2**31 - 1
    assert extend_counter(2**31 - 1, 0xFFFF, 0) == -(2**31)


def test_rejects_nonpositive_resolution():
    with pytest.raises(ValueError):
        new_encoder(0.0)


def test_the_following_error_stays_right_when_the_32_bit_position_wraps():
    """A spindle at 2700 rpm (450 000 counts/s) wraps its 32-bit position after 80 minutes while
    its command runs on: the card's PID, its supervisor and the trace take the difference in 32-bit
    arithmetic, as the card's own subtraction does (a 3-hour polishing job faulted on C there)."""
    import numpy as np

    from cnc_twin.dsp.encoder import count_error, wrap_int32
    from cnc_twin.dsp.pid import new_pid, pid_update

    command = 2.0**31 + 100.5  # counts, past the wrap
    reading = wrap_int32(2**31 + 100)  # what the 32-bit position reads: -2^31 + 100
    assert reading < 0
    assert count_error(command, reading) == 0.5
    assert count_error.py_func(np.array([command, -command]), np.array([reading, -reading], float)).tolist() == [0.5, -0.5]
    gains = dict(kp=30.0, speed_per_volt=0.05, counts_per_unit=1e6, dt=2.5e-4)
    wrapped, plain = new_pid(**gains), new_pid(**gains)
    assert pid_update(wrapped, command, reading, 0.0, 0.0) == pid_update(plain, 100.5, 100.0, 0.0, 0.0)
