"""The spectra's FFT is numpy's, so that the TE core does not import scipy (start-up).

scipy stays the reference: the grid lengths are scipy.fft.next_fast_len's (real input), and
numpy's rfft gives scipy's values (both are pocketfft; equal bit for bit with numpy 2.4,
checked here to 1e-13 of the largest bin so that a numpy upgrade may round differently).
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import scipy.fft
from hypothesis import given, settings
from hypothesis import strategies as st

from rv_te_bench.core.spectrum import _next_fast_len


def test_next_fast_len_is_scipys_for_real_input() -> None:
    got = [_next_fast_len(n) for n in range(1, 20_001)]
    assert got == [scipy.fft.next_fast_len(n, real=True) for n in range(1, 20_001)]


@settings(max_examples=300, deadline=None)
@given(n=st.integers(min_value=1, max_value=10**12))
def test_next_fast_len_is_scipys_for_large_lengths(n: int) -> None:
    assert _next_fast_len(n) == scipy.fft.next_fast_len(n, real=True)


def test_next_fast_len_names_a_bad_length() -> None:
    with pytest.raises(ValueError, match='got 0'):
        _next_fast_len(0)


@pytest.mark.parametrize('n', [4096, 158_000, 160_000, 23_757, 131_073])
def test_numpy_rfft_gives_scipys_values(n: int) -> None:
    x = np.random.default_rng(n).standard_normal(n)
    ours, ref = np.fft.rfft(x), scipy.fft.rfft(x)
    assert ours.shape == ref.shape
    assert np.max(np.abs(ours - ref)) <= 1e-13 * np.max(np.abs(ref))


def test_the_te_core_does_not_import_scipy() -> None:
    """`rv-te analyze --no-advice`, the TE node: 0.15-0.25 s less start-up."""
    code = ('import sys, rv_te_bench.core.stream, rv_te_bench.report.analysis; '
            'print(sorted(m for m in sys.modules if m.split(".")[0] == "scipy"))')
    out = subprocess.run([sys.executable, '-c', code], check=True, capture_output=True,
                         text=True).stdout.strip()
    assert out == '[]'
