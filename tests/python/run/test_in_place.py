"""m3c2kit.compare's reorder_inputs: the engine orders the clouds' own arrays in place instead of
copying them (RunOptions::order_clouds_in_place); the same bits, every row back afterwards, and
a caller's array is never touched without it."""
import numpy as np
import pytest

import m3c2kit
from m3c2kit.engine import OPTIONAL_RESULT_FIELDS, RESULT_FIELDS

from synthetic import noisy_plane_pair

PARAMS = dict(normal_scale=0.5, projection_scale=0.3, max_depth=0.5)


def shuffled_pair(n=60, seed=3):
    """Rows in random order, so that the index's key order differs from the input order."""
    ref, cmp = noisy_plane_pair(n=n)
    rng = np.random.default_rng(seed)
    return np.ascontiguousarray(ref[rng.permutation(len(ref))]), np.ascontiguousarray(cmp[rng.permutation(len(cmp))])


def same_bits(a, b):
    for name in RESULT_FIELDS + OPTIONAL_RESULT_FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        if x is None or y is None:
            assert x is None and y is None, name
            continue
        assert x.dtype == y.dtype and x.tobytes() == y.tobytes(), name


def watcher(arrays, originals):
    """A progress callback recording, at each call, whether every array still equals its original."""
    seen = []

    def progress(done, total):
        seen.append(all(np.array_equal(a, o) for a, o in zip(arrays, originals)))

    return progress, seen


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("explicit_core", [False, True])
def test_reorder_inputs_gives_the_same_bits_and_puts_every_row_back(threads, explicit_core):
    ref, cmp = shuffled_pair()
    core = ref[::7].copy() if explicit_core else None  # None: the reference itself, run in slot order
    expected = m3c2kit.compare(ref, cmp, core, threads=threads, **PARAMS)
    own_ref, own_cmp = ref.copy(), cmp.copy()
    progress, seen = watcher((own_ref, own_cmp), (ref, cmp))
    got = m3c2kit.compare(own_ref, own_cmp, core, threads=threads, progress=progress, reorder_inputs=True, **PARAMS)
    same_bits(expected, got)
    assert seen and not all(seen), "the arrays were ordered in place during the run"
    assert own_ref.tobytes() == ref.tobytes() and own_cmp.tobytes() == cmp.tobytes()
    if not explicit_core:
        assert np.shares_memory(got.core, own_ref) and got.core.tobytes() == ref.tobytes()


def test_a_callers_arrays_are_never_written_without_reorder_inputs():
    ref, cmp = shuffled_pair()
    before = (ref.copy(), cmp.copy())
    progress, seen = watcher((ref, cmp), before)
    m3c2kit.compare(ref, cmp, progress=progress, threads=2, **PARAMS)
    assert seen and all(seen)
    assert ref.tobytes() == before[0].tobytes() and cmp.tobytes() == before[1].tobytes()


def test_read_only_arrays_are_copied_even_when_reordering_is_asked():
    ref, cmp = shuffled_pair()
    expected = m3c2kit.compare(ref, cmp, threads=2, **PARAMS)
    ref.flags.writeable = False
    cmp.flags.writeable = False
    progress, seen = watcher((ref, cmp), (ref.copy(), cmp.copy()))
    got = m3c2kit.compare(ref, cmp, threads=2, progress=progress, reorder_inputs=True, **PARAMS)
    same_bits(expected, got)
    assert seen and all(seen)


def test_runs_reading_a_cloud_in_input_order_keep_the_copy():
    ref, cmp = shuffled_pair()
    expected = m3c2kit.compare(ref, cmp, threads=2, normal_subsample=0.1, **PARAMS)
    progress, seen = watcher((ref, cmp), (ref.copy(), cmp.copy()))
    got = m3c2kit.compare(ref, cmp, threads=2, normal_subsample=0.1, progress=progress, reorder_inputs=True,
                          **PARAMS)
    same_bits(expected, got)
    assert seen and all(seen)
