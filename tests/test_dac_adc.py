"""12-bit DAC (rounding, clamp, saturation count) and the load-cell ADC (half-LSB error, clamp)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from cnc_twin.dsp.adc import adc_convert, new_adc
from cnc_twin.dsp.dac import CODE_MAX, CODE_MIN, dac_write, new_dac

LSB = 10.0 / 2048


@pytest.mark.parametrize(
    "volts, code",
    [(0.0, 0), (LSB * 0.49, 0), (LSB * 0.5, 1), (LSB * 1.49, 1), (-LSB * 0.5, 0), (-LSB * 0.51, -1),
     (5.0, 1024), (-5.0, -1024), (-10.0, -2048), (10.0 - LSB, 2047)],
)
def test_dac_rounds_half_up(volts, code):
    dac = new_dac()
    out = dac_write(dac, volts)
    assert dac["code"] == code
    assert out == pytest.approx(code * LSB)
    assert dac["saturations"] == 0


def test_dac_clamps_and_counts_saturation():
    dac = new_dac()
    assert dac_write(dac, 10.0) == pytest.approx(2047 * LSB) and dac["code"] == CODE_MAX
    assert dac_write(dac, -10.0 - LSB) == pytest.approx(-10.0) and dac["code"] == CODE_MIN
    assert dac_write(dac, 1e6) == pytest.approx(2047 * LSB)
    assert dac_write(dac, 0.1) == pytest.approx(20 * LSB)
    assert dac["saturations"] == 3


def test_a_stuck_dac_outputs_its_code_and_still_counts_what_the_card_writes():
    dac = new_dac()
    dac["stuck"], dac["stuck_code"] = 1, 100
    assert dac_write(dac, 1e6) == pytest.approx(100 * LSB)
    assert dac["code"] == CODE_MAX and dac["saturations"] == 1


@given(st.floats(min_value=-9.99, max_value=9.99))
def test_dac_output_within_half_lsb(volts):
    dac = new_dac()
    assert abs(dac_write(dac, volts) - volts) <= LSB / 2 + 1e-12
    assert dac["saturations"] == 0


@given(st.floats(min_value=-50.0, max_value=149.9))
def test_adc_within_half_lsb_inside_range(force):
    adc = new_adc(-50.0, 150.0, bits=12)
    assert abs(adc_convert(adc, force) - force) <= adc["lsb"] / 2 + 1e-12
    assert 0 <= adc["code"] <= 4095


def test_adc_lsb_and_clamp():
    adc = new_adc(-50.0, 150.0, bits=12)
    assert adc["lsb"] == pytest.approx(200.0 / 4096)
    assert adc_convert(adc, -80.0) == pytest.approx(-50.0) and adc["code"] == 0
    assert adc_convert(adc, 500.0) == pytest.approx(-50.0 + 4095 * adc["lsb"]) and adc["code"] == 4095
    with pytest.raises(ValueError):
        new_adc(1.0, 1.0)
