"""Batches split over threads (:mod:`synth.parallel_rows`): every row once, errors raised after
every block is done, and the compiled kernels' results bit for bit the same on one thread as on
several — each row's work reads and writes only that row."""

from __future__ import annotations

import subprocess
import sys
import threading

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_sixbar_kernel import random_batch  # tests/synth: mixed RPR/RRR six-bars, some not assembling

from synth import parallel_rows
from synth.mechanism.sixbar import PIN_ON_PIVOT_EPS, crank_grid, kernel_inputs, simulate


@pytest.fixture
def threads():
    """Set the thread count for a test; the default is put back after it."""
    yield parallel_rows.set_threads
    parallel_rows.set_threads(parallel_rows._default_threads())


@settings(max_examples=60, deadline=None)
@given(
    st.integers(0, 40),
    st.integers(1, 5),
    st.sampled_from([0, parallel_rows.MIN_WORK_NS - 1, parallel_rows.MIN_WORK_NS]),
)
def test_every_row_once_in_contiguous_blocks(rows, n, size):
    parallel_rows.set_threads(n)
    try:
        seen, blocks, lock = np.zeros(rows, int), [], threading.Lock()

        def work(lo, hi):
            with lock:
                blocks.append((lo, hi))
                seen[lo:hi] += 1

        parallel_rows.over_rows(rows, work, size)
    finally:
        parallel_rows.set_threads(parallel_rows._default_threads())
    assert np.all(seen == 1)
    assert all(lo < hi for lo, hi in blocks) or rows == 0
    split = size >= parallel_rows.MIN_WORK_NS and min(n, rows) > 1
    assert len(blocks) == (min(n, rows) if split else 1)


def test_an_error_in_a_block_is_raised_once_every_block_is_done(threads):
    threads(4)
    done, lock = [], threading.Lock()

    def work(lo, hi):
        if lo == 0:
            raise ZeroDivisionError("first block")
        threading.Event().wait(0.05)  # the others finish after the first failed
        with lock:
            done.append(lo)

    with pytest.raises(ZeroDivisionError, match="first block"):
        parallel_rows.over_rows(8, work, 10**9)
    assert sorted(done) == [2, 4, 6]


@pytest.mark.parametrize("order", [0, 2])
def test_six_bar_motion_the_same_on_any_number_of_threads(threads, order):
    from synth.mechanism import sixbar_kernel
    from synth.mechanism.sixbar_kernel import output_angles

    batch = random_batch(300, seed=3)
    params, rpr = kernel_inputs(batch)
    rows_phi = np.random.default_rng(4).uniform(0, 2 * np.pi, (300, 40))
    results = []
    known = set(sixbar_kernel._positions.signatures)  # other tests in this process may add theirs
    for n in (1, 2, 3):
        threads(n)
        motion = simulate(batch, crank_grid(360), order=order)
        results.append(
            [
                motion.psi,
                motion.z[0],
                motion.moving_pivot,
                motion.status,
                *motion.dpsi,
                motion.transmission_output,
                output_angles(params, rpr, rows_phi, PIN_ON_PIVOT_EPS),
            ]
        )
    for other in results[1:]:
        for a, b in zip(results[0], other):
            np.testing.assert_array_equal(a, b)
    assert np.any(results[0][3] != 0) and np.any(results[0][3] == 0)  # flagged positions among them
    # unsplit (contiguous pages) and split (strided pages), ψ alone or the whole motion: one
    # compile, its pages typed any-layout (a C-layout signature would be a second compile)
    assert len(set(sixbar_kernel._positions.signatures) - known) <= 1
    for signature in sixbar_kernel._positions.signatures:
        assert all(signature[i].layout == "A" for i in sixbar_kernel._POSITIONS_PAGES), signature


def test_one_signature_serves_contiguous_strided_and_read_only_arrays():
    import numba

    @numba.njit
    def weighted_sums(x, w, out):
        for i in range(x.shape[0]):
            out[i] = x[i].sum() * w[i]

    x = np.arange(12.0).reshape(3, 4)
    w = np.array([1.0, 2.0, 3.0])
    frozen = w.copy()
    frozen.flags.writeable = False
    out = np.empty(3)
    parallel_rows.one_signature(weighted_sums, (x, w, out), any_layout=(0,), read_only=(1,))
    weighted_sums(x, w, out)  # C-contiguous, writable
    np.testing.assert_array_equal(out, [6.0, 44.0, 114.0])
    weighted_sums(x[:, 1:3], frozen, out)  # strided, read-only
    np.testing.assert_array_equal(out, [3.0, 22.0, 57.0])
    assert len(weighted_sums.signatures) == 1
    # another dtype is not a layout: it gets a compile of its own
    parallel_rows.one_signature(weighted_sums, (x.astype(np.int64), w, out), any_layout=(0,), read_only=(1,))
    weighted_sums(x.astype(np.int64)[:, :2], w, out)
    np.testing.assert_array_equal(out, [1.0, 18.0, 51.0])
    assert len(weighted_sums.signatures) == 2
    # asked again for kinds it has seen (a strided block of the first), it compiles nothing
    parallel_rows.one_signature(weighted_sums, (x[:, 1:3], w, out), any_layout=(0,), read_only=(1,))
    assert len(weighted_sums.signatures) == 2


def test_clearances_band_windows_and_vertex_bounds_the_same_on_any_number_of_threads(threads):
    from synth.mechanism.band_windows import longest_windows
    from synth.mechanism.buildability import clearances
    from synth.mechanism.sample_ranges import vertex_bounds

    batch = random_batch(200, seed=5)
    motion = simulate(batch, crank_grid(720), order=0)
    E = np.concatenate([motion.psi, motion.psi + (motion.psi[:, -1:] - motion.psi[:, :1])], axis=1)
    band = np.full(200, np.radians(0.5))
    results = []
    for n in (1, 3):
        threads(n)
        upper, lower = vertex_bounds(E)
        results.append([*clearances(batch, motion)[:3], upper, lower, *longest_windows(upper, lower, band, 720)])
    for a, b in zip(*results):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("value", ["0", "two", "-1"])
def test_a_bad_thread_count_is_one_line_and_exit_2(value):
    env = {"DWELL_THREADS": value, "PATH": ""}
    command = [sys.executable, "-c", "import sys; from cli.main import main; sys.exit(main())", "--version"]
    proc = subprocess.run(command, capture_output=True, text=True, env=env, timeout=60, check=False)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "DWELL_THREADS" in proc.stderr and repr(value) in proc.stderr
