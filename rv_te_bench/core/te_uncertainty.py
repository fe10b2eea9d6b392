"""Uncertainty budgets of the TE results: TE p-p, spectrum lines, hysteresis metrics.

The measurement model (Wang 2020 Eq. 22 with the encoders' errors, :mod:`.bench_uncertainty`)::

    TE_meas(phi) = TE(phi) + e_out(theta_out) - e_in(theta_in) / i + omega_out(t) tau + n(t)

with e_* the encoders' error functions (harmonics of unknown phase, interpolation error,
quantisation), tau the timing skew of the output channel against the input channel and n
the read-head noise. Every result below is a functional of TE_meas; its inputs:

* **harmonic encoder errors** (graduation orders, mounting eccentricity, interpolation):
  a result that is a linear combination sum_j c_j TE(phi_j) of the TE at points phi_j sees
  a component g sin(k theta + rho) of unknown phase rho as g |sum_j c_j e^{i k theta_j}|
  sin(rho'): an arcsine input of amplitude g with the closed-form sensitivity
  |sum_j c_j exp(i k theta_j)| (theta_out = phi, theta_in = i phi at the points). The TE
  p-p is max - min: by the envelope theorem its first-order change is the change at the
  two extremes (c = +1 at the maximum, -1 at the minimum), so
  c_k = 2 |sin(k Delta / 2)| with Delta the angle between them. A spectrum line of output
  order o sees only a component of that order (amplitude: c = 1; phase: c = 1 / A).
* **fast errors at the extremes of the p-p** (interpolation error within one signal
  period, read-head noise): the maximum of samples over a flat top that spans many signal
  periods picks their crest, so the p-p of samples reads high by up to
  ``2 (a_out + a_in / i + z sigma)`` (z = sqrt(2 ln n), n samples per revolution): an
  uncorrected one-sided bias, bounded and added to U (``bias_bound``, GUM F.2.4.5).
* **quantisation**: the floor of the count, -q/2 on average (cancels in every difference)
  +-q/2 rectangular at each point read.
* **DAQ timing skew**: the output channel latched tau late adds omega_out tau: a constant
  at constant speed (p-p: c = spread of the reference speed; a line of order o turns by
  o omega_out tau, its amplitude is unchanged).
* **temperature**: a scale whose expansion differs from its mount's by alpha reads
  alpha delta T x the angle turned (c = alpha |theta_max - theta_min|).
* **the test's own resolution**: samples miss the true extreme of the TE by at most
  A o^2 (d phi)^2 / 8 (the dominant line A at order o, sample spacing d phi); the cubic
  resampling of the order spectrum changes an amplitude by 0.015 (2 pi / s)^4 relative
  (s samples per period of the line).
* **type A**: the spread of the result over the windows / revolutions of the same run
  (the p-p of one revolution: s, n - 1 dof; a line averaged over n windows: s / sqrt(n)).
  Noise and quantisation are in that spread; without a repeat (one window) they are
  entered as type B instead.

The hysteresis metrics' budgets are in :mod:`.hysteresis_uncertainty`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.core.uncertainty import Budget, UncertaintyInput, combine, type_a, type_b

if TYPE_CHECKING:
    from collections.abc import Sequence

    import numpy.typing as npt

    from rv_te_bench.core.bench_uncertainty import BenchUncertainty, EncoderErrorModel

__all__ = [
    'extreme_candidates',
    'extreme_reach',
    'harmonic_inputs',
    'line_budgets',
    'te_pp_budget',
]

_TWO_PI = 2.0 * math.pi
#: Relative amplitude error of the cubic Lagrange resampler per (2 pi / s)^4.
RESAMPLE_AMPLITUDE_COEFF = 0.015


def harmonic_inputs(enc: EncoderErrorModel, who: str, theta_rad: npt.ArrayLike,
                    weights: npt.ArrayLike, *, scale: float = 1.0,
                    components: Sequence[tuple[str, int, float]] | None = None,
                    ) -> list[UncertaintyInput]:
    """Arcsine inputs of an encoder's harmonic errors on sum_j c_j e(theta_j).

    Args:
        enc: The encoder's error model.
        who: ``'output encoder'`` / ``'input encoder'`` (the inputs' names start with it).
        theta_rad: Shaft angles theta_j where the result reads the TE [rad].
        weights: c_j, the result's weight of the TE at each point.
        scale: Factor from the shaft's angle error to TE (1 output, -1/i input: sign free).
        components: (name, order, amplitude) to use (default: every component).

    Returns:
        One input per component: half-width (amplitude) g, sensitivity
        |scale| |sum_j c_j exp(i k theta_j)| (closed form).
    """
    th = np.asarray(theta_rad, dtype=np.float64)
    c = np.asarray(weights, dtype=np.float64)
    out = []
    for name, order, g in (enc.components() if components is None else components):
        s = abs(scale) * float(abs(np.sum(c * np.exp(1j * order * th))))
        out.append(type_b(f'{who}: {name}', sensitivity=s, distribution='arcsine',
                          half_width=g, source=enc.source,
                          note=f'closed form |sum_j c_j exp(i {order} theta_j)|'))
    return out


def te_pp_budget(measurand: str, value_rad: float, *, phi_max_rad: float, phi_min_rad: float,
                 gear_ratio: float, bench: BenchUncertainty,
                 per_revolution_rad: npt.ArrayLike | None = None,
                 speed_spread_rad_s: float = 0.0, samples_per_rev: float = math.nan,
                 dominant: tuple[float, float] | None = None,
                 theta_out_offset_rad: float = 0.0,
                 other_extremes: Sequence[tuple[float, float]] = ()) -> Budget:
    """The budget of a TE peak-to-peak value.

    When the record has near-equal peaks (a 2K-V's crank-order ripple under a slow
    output-order wave), the encoder error may move the maximum (minimum) from one to
    another: ``other_extremes`` lists the other (phi_max, phi_min) pairs within reach, and
    each harmonic's sensitivity is the largest over all pairs (the envelope theorem holds
    for whichever pair is the extreme of the corrected record).

    Args:
        measurand: Its name (``'te_pp_ccw_rad'``).
        value_rad: The p-p [rad].
        phi_max_rad, phi_min_rad: Output angle theta_in / i of the TE maximum and minimum
            [rad] (unwrapped: whole revolutions between them count for the input shaft).
        gear_ratio: i.
        bench: The bench's type B inputs.
        per_revolution_rad: p-p of each revolution (or window) of the run: type A (the
            spread of one revolution's p-p, n - 1 dof); None or one value: noise and
            quantisation from the data sheet instead.
        speed_spread_rad_s: Spread of the output reference speed over the record [rad/s]
            (skew sensitivity; 0 at a constant drive speed).
        samples_per_rev: Samples per output revolution (sampling resolution, fast-error
            bias); NaN: not known.
        dominant: (amplitude [rad], output order) of the dominant line (peak curvature).
        theta_out_offset_rad: Output encoder angle at phi = 0 (its zero) [rad].
        other_extremes: Further (phi_max, phi_min) candidates (see above).
    """
    i = float(gear_ratio)
    w = np.array([1.0, -1.0])
    eo, ei = bench.encoder_out, bench.encoder_in
    inputs: list[UncertaintyInput | None] = []
    pairs = [(phi_max_rad, phi_min_rad), *other_extremes]
    for enc, who, turns, sc in ((eo, 'output encoder', 1.0, 1.0),
                                (ei, 'input encoder', i, 1.0 / i)):
        per_pair = [harmonic_inputs(enc, who, turns * np.array(p) + (
            theta_out_offset_rad if turns == 1.0 else 0.0), w, scale=sc,
            components=enc.long_range_components()) for p in pairs]
        inputs += [max(xs, key=lambda x: x.sensitivity) for xs in zip(*per_pair, strict=True)]
    for enc, who, sc in ((eo, 'output encoder', 1.0), (ei, 'input encoder', 1.0 / i)):
        if enc.resolution_rad > 0:
            inputs.append(type_b(f'{who}: quantisation at the two extremes',
                                 sensitivity=sc * math.sqrt(2.0), distribution='rectangular',
                                 half_width=enc.resolution_rad / 2.0, source=enc.source,
                                 note='two points, +-q/2 each (the -q/2 mean cancels)'))
    rev = None if per_revolution_rad is None else type_a(
        'repeatability: p-p of one revolution over the run', per_revolution_rad,
        of_mean=False, note='spread of the per-revolution (per-window) p-p, one observation')
    notes = []
    if rev is None:
        for enc, who, sc in ((eo, 'output encoder', 1.0), (ei, 'input encoder', 1.0 / i)):
            if enc.noise_sigma_rad > 0:
                inputs.append(type_b(f'{who}: read-head noise at the two extremes',
                                     sensitivity=sc * math.sqrt(2.0), distribution='normal',
                                     u=enc.noise_sigma_rad, source=enc.source))
        notes.append('one revolution only: no type A repeatability; noise from the data sheet')
    else:
        inputs.append(rev)
    inputs.append(type_b('DAQ timing skew between the channels', sensitivity=speed_spread_rad_s,
                         distribution='rectangular', half_width=bench.daq_skew_s, unit='s',
                         source=bench.source,
                         note='closed form: omega_out(t_max) - omega_out(t_min)'))
    for enc, who, span in ((eo, 'output encoder', abs(phi_max_rad - phi_min_rad)),
                           (ei, 'input encoder', abs(phi_max_rad - phi_min_rad))):
        inputs.append(type_b(f'{who}: temperature (scale/mount expansion mismatch)',
                             sensitivity=enc.cte_mismatch_per_k * span,
                             distribution='rectangular',
                             half_width=bench.temperature_spread_k / 2.0, unit='K',
                             source=enc.source, note='alpha_mismatch x angle between extremes'))
    if dominant is not None and math.isfinite(samples_per_rev) and samples_per_rev > 0:
        amp, order = dominant
        d_phi = _TWO_PI / samples_per_rev
        inputs.append(type_b('sampling: extremes between samples', sensitivity=math.sqrt(2.0),
                             distribution='rectangular',
                             half_width=abs(amp) * (order * d_phi) ** 2 / 8.0,
                             source='this record (sample spacing, dominant line)',
                             note='A o^2 dphi^2 / 8 at each extreme'))
    n_rev = samples_per_rev if math.isfinite(samples_per_rev) and samples_per_rev > 1 else 1e4
    z = math.sqrt(2.0 * math.log(n_rev))
    fast = 0.0
    for enc, sc in ((eo, 1.0), (ei, 1.0 / i)):
        a = enc.interpolation_rad if enc.signal_periods > 0 else 0.0
        fast += sc * (a + z * enc.noise_sigma_rad)
    bias = 2.0 * fast
    if bias > 0:
        notes.append(f'the p-p of samples reads the crest of the fast errors (interpolation, '
                     f'noise) at both extremes: up to +{bias:.3g} rad, not corrected, '
                     'added to U (GUM F.2.4.5)')
    notes += _unknown_notes(bench)
    return combine(measurand, value_rad, inputs, notes=notes, bias_bound=bias)


def line_budgets(label: str, amplitude_rad: float, phase_rad: float, output_order: float, *,
                 gear_ratio: float, bench: BenchUncertainty, output_hz: float,
                 window_amplitudes_rad: npt.ArrayLike | None = None,
                 window_phases_rad: npt.ArrayLike | None = None,
                 samples_per_rev: float = math.nan, n_samples: int = 0,
                 ) -> tuple[Budget, Budget]:
    """Budgets of a spectrum line's amplitude and phase (averaged over complete windows).

    Args:
        label: The line's label (``'1 f_w'``).
        amplitude_rad, phase_rad: The averaged line [rad].
        output_order: o, cycles per output revolution.
        gear_ratio: i.
        bench: The bench's type B inputs.
        output_hz: Mean output rotation frequency [Hz] (skew sensitivity of the phase).
        window_amplitudes_rad, window_phases_rad: The line in each complete window (type
            A; the averaged amplitude is their mean, the phase that of the mean phasor).
        samples_per_rev: Grid points per output revolution of the spectrum.
        n_samples: Samples analysed (noise when there is no type A).
    """
    i = float(gear_ratio)
    amp = float(amplitude_rad)
    a_in: list[UncertaintyInput | None] = []
    p_in: list[UncertaintyInput | None] = []
    for enc, who, per_out in ((bench.encoder_out, 'output encoder', 1.0),
                              (bench.encoder_in, 'input encoder', i)):
        for name, k, g in enc.components():
            if abs(k * per_out - output_order) <= 1e-9 * max(1.0, output_order):
                sc = 1.0 if per_out == 1.0 else 1.0 / i
                a_in.append(type_b(f'{who}: {name}', sensitivity=sc, distribution='arcsine',
                                   half_width=g, source=enc.source,
                                   note='closed form: a phasor of the same order'))
                p_in.append(type_b(f'{who}: {name}', sensitivity=sc / amp if amp > 0 else 0.0,
                                   distribution='arcsine', half_width=g, source=enc.source,
                                   note='closed form: 1 / A'))
    for enc, who, per_out, sc in ((bench.encoder_out, 'output encoder', 1.0, 1.0),
                                  (bench.encoder_in, 'input encoder', i, 1.0 / i)):
        n_per = enc.signal_periods * per_out
        if (enc.interpolation_rad > 0 and n_per > 0 and n_samples > 0
                and math.isfinite(samples_per_rev) and n_per > samples_per_rev / 2):
            u_alias = sc * enc.interpolation_rad / math.sqrt(n_samples)
            a_in.append(type_b(f'{who}: interpolation error aliased by the sampling',
                               sensitivity=1.0, distribution='normal', u=u_alias,
                               source=enc.source,
                               note='undersampled: spread like noise, a / sqrt(N)'))
            p_in.append(type_b(f'{who}: interpolation error aliased by the sampling',
                               sensitivity=1.0 / amp if amp > 0 else 0.0,
                               distribution='normal', u=u_alias, source=enc.source,
                               note='undersampled: spread like noise, a / sqrt(N) / A'))
    omega = _TWO_PI * output_hz if math.isfinite(output_hz) else 0.0
    p_in.append(type_b('DAQ timing skew between the channels',
                       sensitivity=output_order * omega, distribution='rectangular',
                       half_width=bench.daq_skew_s, unit='s', source=bench.source,
                       note='closed form: o omega_out'))
    if math.isfinite(samples_per_rev) and samples_per_rev > 0 and output_order > 0:
        s = samples_per_rev / output_order
        a_in.append(type_b('resampling to the angle grid (cubic)', sensitivity=1.0,
                           distribution='rectangular',
                           half_width=amp * RESAMPLE_AMPLITUDE_COEFF * (_TWO_PI / s) ** 4,
                           source='core.spectrum resampler', note='0.015 (2 pi / s)^4 A'))
    ta = None if window_amplitudes_rad is None else type_a(
        'repeatability over the windows', window_amplitudes_rad)
    tp = None
    if window_phases_rad is not None:
        ph = np.asarray(window_phases_rad, dtype=np.float64)
        dev = np.angle(np.exp(1j * (ph - phase_rad)))
        tp = type_a('repeatability over the windows', dev)
    notes = []
    if ta is None:
        var = 0.0
        for enc, sc in ((bench.encoder_out, 1.0), (bench.encoder_in, 1.0 / i)):
            var += sc * sc * (enc.noise_sigma_rad ** 2 + enc.resolution_rad ** 2 / 12.0)
        u_line = math.sqrt(2.0 * var / n_samples) if n_samples > 0 else 0.0
        a_in.append(type_b('noise and quantisation (one window)', sensitivity=1.0,
                           distribution='normal', u=u_line, source='data sheet',
                           note='sigma sqrt(2 / N) per quadrature'))
        p_in.append(type_b('noise and quantisation (one window)',
                           sensitivity=1.0 / amp if amp > 0 else 0.0, distribution='normal',
                           u=u_line, source='data sheet', note='sigma sqrt(2 / N) / A'))
        notes.append('one complete window: no type A repeatability; noise from the data sheet')
    else:
        a_in.append(ta)
        p_in.append(tp)
    notes += _unknown_notes(bench)
    return (combine(f'line {label} amplitude', amp, a_in, notes=notes),
            combine(f'line {label} phase', float(phase_rad), p_in, notes=notes))


def _unknown_notes(bench: BenchUncertainty) -> list[str]:
    return [f'{who} model {e.model!r} is not known: its graduation and interpolation errors '
            'are not in the budget (state them in the bench description)'
            for who, e in (('input encoder', bench.encoder_in),
                           ('output encoder', bench.encoder_out)) if not e.known]


#: Bins of one output revolution the extremes are located on.
EXTREME_BINS = 720
#: Near-equal peaks (dips) kept as candidates for the extreme, the nearest in value first.
MAX_EXTREME_CANDIDATES = 6


def extreme_candidates(phi_rad: npt.ArrayLike, te_rad: npt.ArrayLike, reach_rad: float,
                       ) -> tuple[tuple[float, float], list[tuple[float, float]]] | None:
    """Where a TE record has its maximum and minimum on one output revolution, and which
    other peaks and dips the encoder errors could make the extreme.

    The record is folded on phi mod 2 pi into :data:`EXTREME_BINS` bins (mean TE per bin:
    a unit's pattern repeats every revolution); the extremes are the bins of the largest
    and smallest mean; the candidates the other local maxima (minima) within ``reach_rad``
    of them (a 2K-V's crank-order ripple under a slow output-order wave has near-equal
    peaks).

    Args:
        phi_rad: Output angle theta_in / i of each sample [rad].
        te_rad: TE at those samples [rad] (NaN rows skipped).
        reach_rad: How far below the maximum (above the minimum) a peak (dip) may lie.

    Returns:
        ((phi_max, phi_min), [other (phi_max, phi_min) pairs]) [rad], or None when the
        record covers less than a quarter of the bins.
    """
    phi = np.asarray(phi_rad, dtype=np.float64)
    te = np.asarray(te_rad, dtype=np.float64)
    ok = np.isfinite(phi) & np.isfinite(te)
    if np.count_nonzero(ok) < 8:
        return None
    nb = EXTREME_BINS
    p = np.mod(phi[ok], _TWO_PI)
    k = np.minimum((p / _TWO_PI * nb).astype(np.int64), nb - 1)
    n = np.bincount(k, minlength=nb)
    if np.count_nonzero(n) < nb // 4:
        return None
    mean = np.where(n > 0, np.bincount(k, weights=te[ok], minlength=nb) / np.maximum(n, 1),
                    np.nan)
    centres = (np.arange(nb) + 0.5) * _TWO_PI / nb
    top, bottom = int(np.nanargmax(mean)), int(np.nanargmin(mean))
    filled = np.where(np.isfinite(mean), mean, np.nanmean(mean))
    left, right = np.roll(filled, 1), np.roll(filled, -1)
    peaks = np.flatnonzero((filled >= left) & (filled >= right)
                           & (filled >= filled[top] - reach_rad))
    dips = np.flatnonzero((filled <= left) & (filled <= right)
                          & (filled <= filled[bottom] + reach_rad))
    peaks = peaks[np.argsort(-filled[peaks])][:MAX_EXTREME_CANDIDATES]
    dips = dips[np.argsort(filled[dips])][:MAX_EXTREME_CANDIDATES]
    others = [(float(centres[a]), float(centres[b])) for a in peaks for b in dips
              if (int(a), int(b)) != (int(top), int(bottom))]
    return (float(centres[top]), float(centres[bottom])), others


def extreme_reach(bench: BenchUncertainty, gear_ratio: float) -> float:
    """How far the encoders' long-range errors can move one peak against another: twice
    the sum of their harmonic amplitudes (the input's divided by i) [rad]."""
    return (2.0 * sum(g for _, _, g in bench.encoder_out.long_range_components())
            + 2.0 * sum(g for _, _, g in bench.encoder_in.long_range_components())
            / gear_ratio)
