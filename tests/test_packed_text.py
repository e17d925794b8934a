"""A program's text held packed (:class:`~cnc_twin.core.packed_text.PackedText`) gives back the text
and writes the bytes ``write_text`` writes, whatever the text and however it is cut in pieces."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_twin.core.packed_text import PackedText


@settings(max_examples=60, deadline=None)
@given(text=st.text(st.characters(blacklist_categories=("Cs",)), max_size=300), piece=st.integers(1, 40))
def test_packed_text_is_the_text_and_writes_its_utf8(tmp_path_factory, text, piece):
    folder = tmp_path_factory.mktemp("packed")
    packed = PackedText.of(text, piece=piece)
    assert packed.text() == text and packed.chars == len(text)
    packed.write(folder / "packed.ngc", piece=max(1, piece // 3))
    (folder / "plain.ngc").write_text(text, encoding="utf-8")
    assert (folder / "packed.ngc").read_bytes() == (folder / "plain.ngc").read_bytes()


def test_a_cam_program_packs_to_a_small_share_of_its_text():
    lines = "".join(f"G1 X{0.1 * k:.4f} Y{12.5 + 0.001 * k:.4f} Z{-0.25 + 1e-4 * (k % 97):.4f}\n" for k in range(20000))
    assert len(PackedText.of(lines).data) < 0.3 * len(lines)
