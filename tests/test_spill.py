"""Arrays kept on disk until the run's end (:class:`~cnc_twin.core.spill.StoredArray`): given back
bit for bit, in their own process and, pickled, in another; nothing left on disk."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import tempfile

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from cnc_twin.core.spill import StoredArray


@settings(max_examples=40, deadline=None)
@given(array=hnp.arrays(st.sampled_from([np.float64, np.int32, np.int16]), hnp.array_shapes(max_dims=2, max_side=60)),
       spill_bytes=st.sampled_from([0, 1, 64, 1 << 30]))
def test_a_stored_array_is_given_back_bit_for_bit(array, spill_bytes):
    stored = StoredArray(array, spill_bytes=spill_bytes)
    assert stored.spilled == (array.nbytes >= spill_bytes)
    back = stored.array()
    assert back.dtype == array.dtype and back.shape == array.shape
    assert back.tobytes() == array.tobytes()  # NaNs and -0.0 alike
    assert pickle.loads(pickle.dumps(stored)).array().tobytes() == array.tobytes()


def test_a_pickled_stored_array_carries_its_values_to_another_process():
    values = np.random.default_rng(7).normal(size=(20001, 3))
    stored = StoredArray(values)
    assert stored.spilled
    script = ("import pickle, sys; s = pickle.load(sys.stdin.buffer); a = s.array(); "
              "sys.stdout.write(f'{s.spilled} {a.shape} {a.tobytes().hex()[:64]} {float(a.sum())!r}')")
    out = subprocess.run([sys.executable, "-c", script], input=pickle.dumps(stored), capture_output=True, check=True)
    assert out.stdout.decode() == (f"False {values.shape} {values.tobytes().hex()[:64]} {float(values.sum())!r}")


def test_the_spill_file_leaves_nothing_on_disk():
    before = set(os.listdir(tempfile.gettempdir()))
    stored = [StoredArray(np.full((5000, 3), float(k))) for k in range(4)]
    assert all(s.spilled for s in stored)
    assert [float(s.array()[-1, -1]) for s in stored] == [0.0, 1.0, 2.0, 3.0]
    assert not [name for name in set(os.listdir(tempfile.gettempdir())) - before if "spill" in name]
