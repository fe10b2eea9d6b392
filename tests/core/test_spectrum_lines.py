"""Unassigned spectrum lines (issue 33 point 5): every line above the threshold that no
labelled part explains is listed, none dropped, none forced onto a part's label. Spectra
made here by numpy's FFT of known sums of cosines (the truth is the amplitudes put in)."""

from __future__ import annotations

import numpy as np
import pytest

from rv_te_bench.core.spectrum_lines import line_threshold_rad, unassigned_lines


def spectrum(components: dict[float, float], revolutions: int = 1, n_per_rev: int = 1024,
             noise_rad: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Orders and one-sided peak amplitudes of sum a cos(k phi) over whole revolutions."""
    n = n_per_rev * revolutions
    phi = 2 * np.pi * revolutions * np.arange(n) / n
    te = sum(a * np.cos(k * phi + 0.3 * k) for k, a in components.items())
    te = te + np.random.default_rng(1).normal(0.0, noise_rad, n)
    x = np.fft.rfft(te) / n
    amp = 2 * np.abs(x)
    amp[0] /= 2
    return np.arange(amp.size) / revolutions, amp


def test_an_unlabelled_line_larger_than_the_labelled_ones_is_listed() -> None:
    # the issue's demo case: f_out and crank lines labelled, an order-2 line of 0.15'
    arcmin = np.pi / 180 / 60
    orders, amp = spectrum({1: 0.5 * arcmin, 2: 0.15 * arcmin, 25: 0.08 * arcmin,
                            24: 0.01 * arcmin, 26: 0.01 * arcmin}, noise_rad=1e-4 * arcmin)
    lost = unassigned_lines(orders, amp, [1.0, 25.0, 24.0, 26.0, 50.0])
    assert [u.output_order for u in lost] == [2.0]
    assert lost[0].amplitude_rad == pytest.approx(0.15 * arcmin, rel=1e-3)


def test_every_line_above_the_threshold_strongest_first_mean_and_labelled_left_out() -> None:
    orders, amp = spectrum({0: 5.0, 3: 1e-3, 7: 4e-3, 9: 2e-3, 11: 1e-6}, noise_rad=1e-7)
    lost = unassigned_lines(orders, amp, [9.0])
    assert [u.output_order for u in lost] == [7.0, 3.0]    # 0 is the mean, 9 is labelled
    thr = line_threshold_rad(orders, amp)
    # 1 % of the strongest (4e-3) is above ten noise floors (the median bin ~1e-8 here)
    assert thr == pytest.approx(4e-5, rel=1e-3)
    assert all(u.amplitude_rad >= thr for u in lost)        # 11 (1e-6) is below it


def test_two_revolutions_half_orders_and_the_half_bin_rule() -> None:
    orders, amp = spectrum({1: 1e-3, 1.5: 5e-4, 4: 3e-4}, revolutions=2)
    assert orders[1] == 0.5
    lost = unassigned_lines(orders, amp, [1.0, 4.3])   # 4.3 is 0.3 from 4: over half a bin
    assert [u.output_order for u in lost] == [1.5, 4.0]
    assert unassigned_lines(orders, amp, [1.0, 1.5, 4.2]) == []   # 0.2 from 4: within it


def test_nothing_to_list() -> None:
    assert unassigned_lines([0.0], [1.0], []) == []
    assert unassigned_lines([], [], []) == []
    with pytest.raises(ValueError, match='differ in length: 2 vs 1'):
        unassigned_lines([0.0, 1.0], [1.0], [])
