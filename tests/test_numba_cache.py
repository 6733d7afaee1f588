"""The compiled kernels' cache stamp (``chekhov._numba_cache``): a kernel is recompiled when any
kernel module changes, not only its own file."""

from __future__ import annotations

import numpy as np
from numba import njit

from chekhov import _numba_cache
from chekhov.collision import validity
from chekhov.robot import chain_kinematics


def _locator(dispatcher):
    return dispatcher._cache._impl.locator


def test_chekhov_kernels_are_stamped_with_every_kernel_source():
    """Each of chekhov's cached kernels (one inlining another module's function among them)
    has the package stamp; a kernel defined elsewhere keeps numba's own."""
    digest = _numba_cache.kernel_sources_digest()
    for kernel in (validity.valid_batch, chain_kinematics.ik_batch):
        loc = _locator(kernel)
        assert isinstance(loc, _numba_cache._PackageStamp), type(loc)
        assert loc.get_source_stamp() == digest

    @njit(cache=True)
    def elsewhere(x):  # this test file is outside the package
        return x + 1

    assert elsewhere(np.int64(1)) == 2
    assert not isinstance(_locator(elsewhere), _numba_cache._PackageStamp)


def test_the_stamp_changes_with_any_kernel_file_and_only_with_them(tmp_path):
    """Editing a module with a kernel changes the digest, editing one without does not, and
    so does adding a kernel module."""
    (tmp_path / "sub").mkdir()
    (tmp_path / "a.py").write_text("from numba import njit\n@njit\ndef f(x):\n    return x\n")
    (tmp_path / "sub" / "b.py").write_text("def g():\n    return 1\n")
    d0 = _numba_cache.sources_digest(tmp_path)
    (tmp_path / "sub" / "b.py").write_text("def g():\n    return 2\n")
    assert _numba_cache.sources_digest(tmp_path) == d0
    (tmp_path / "a.py").write_text("from numba import njit\n@njit\ndef f(x):\n    return 2 * x\n")
    d1 = _numba_cache.sources_digest(tmp_path)
    assert d1 != d0
    (tmp_path / "sub" / "c.py").write_text("from numba import njit\n")
    assert _numba_cache.sources_digest(tmp_path) != d1
    assert _numba_cache.install()   # installed once, idempotent
