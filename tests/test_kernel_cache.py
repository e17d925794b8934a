"""numba's cache is purged when a module the cached kernels call changes (numba checks only the
kernel's own file)."""

from __future__ import annotations

from cnc_twin.core.kernel_cache import purge_stale


def test_cached_kernels_are_removed_when_a_dependency_changes(tmp_path):
    module, dep = tmp_path / "batch.py", tmp_path / "stepper.py"
    module.write_text("x = 1\n")
    dep.write_text("def step(): return 1\n")
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    files = [cache / "batch.run-10.py311.nbi", cache / "batch.run-10.py311.1.nbc"]
    other = cache / "stepper.step-1.py311.nbi"
    for f in files + [other]:
        f.write_bytes(b"machine code")
    assert purge_stale(module, [dep])          # no fingerprint yet: whatever is cached is suspect
    assert not any(f.exists() for f in files) and other.exists()
    for f in files:
        f.write_bytes(b"machine code")        # numba caches the kernels again
    assert not purge_stale(module, [dep])      # nothing changed: the cache stays
    assert all(f.exists() for f in files)
    dep.write_text("def step(): return 2\n")   # the stepper changed
    assert purge_stale(module, [dep])
    assert not any(f.exists() for f in files)
