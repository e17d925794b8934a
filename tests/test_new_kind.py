"""A new record type plugs in at one place per side: its wire entry (whiteboard/payloads.py's
table) and what the card does with it (dsp/record_intake.py's MODAL or ACCEPT, the interpolator's
START / ADVANCE for a moving kind). Here a toy modal record, "set the program mark from a tone",
is added in exactly those two entries and goes through the codec and the card's queue."""

from __future__ import annotations

import struct
from dataclasses import dataclass

import pytest

from cnc_twin.dsp import record_intake
from cnc_twin.dsp.interpolator import SegmentInterpolator
from cnc_twin.scenario.resources import default_scenario
from cnc_twin.scenario.load import load_scenario
from cnc_twin.whiteboard import payloads
from cnc_twin.whiteboard.codec import RecordError, decode, encode
from cnc_twin.whiteboard.records import EndOfProgram, WireRecord

_TONE = struct.Struct("<I")


@dataclass(frozen=True)
class Tone(WireRecord):
    """The toy record: a number the card shows as the program mark."""

    hertz: int


@pytest.fixture
def tone_kind(monkeypatch):
    entry = payloads.Payload(99, Tone, lambda r: _TONE.pack(r.hertz), lambda p, _: Tone(_TONE.unpack(p)[0]),
                             _TONE.size // 2)
    monkeypatch.setitem(payloads.BY_KIND, Tone, entry)  # the wire: one entry
    monkeypatch.setitem(payloads.BY_CODE, 99, entry)
    monkeypatch.setitem(record_intake.MODAL, Tone, lambda interp, r: setattr(interp, "mark", r.hertz))  # the card


def test_a_toy_record_added_at_one_place_per_side_runs_through_codec_and_card(tone_kind):
    seq, record = decode(encode(Tone(440), 7))
    assert (seq, record) == (7, Tone(440))
    sc = load_scenario(default_scenario())
    interp = SegmentInterpolator(axes=sc.axes, power_on=sc.home, period=sc.timing.interpolation_period)
    interp.push(1, record)
    interp.push(2, EndOfProgram())
    interp.next_period()
    assert interp.mark == 440 and interp.finished and interp.last_seq_executed == 2


def test_without_its_wire_entry_the_toy_record_is_refused():
    with pytest.raises(TypeError):
        encode(Tone(440), 1)
    words = encode(EndOfProgram(), 1)
    words[0] = (words[0] & 0xFF00) | 99  # a type code nobody registered
    with pytest.raises(RecordError):
        decode(words)
