"""Offline analysis of synthetic bags with a known TE: statistics and spectrum lines.

The TE written is mean + sum a_k cos(k phi + p_k), phi = theta_in / i, so

* statistics over all samples equal numpy's max/min/mean/std of the written TE array
  (independent computation, rtol 1e-9);
* over one whole output revolution of N uniform samples the mean of each cosine is exactly
  zero, so a complete window's mean is the written mean (atol 1e-12 rad);
* p-p and amplitude approach the closed form on a dense grid (sampling loses at most
  a (1 - cos(pi / s)) with s samples per cycle: 0.3 % at s = 40, tolerance 0.5 %);
* each spectrum line returns its a_k and p_k: at constant speed the angle grid is the
  sample grid (rtol 1e-6, atol 1e-6 rad on the phase); at varying speed the cubic
  resampling costs ~0.015 (2 pi / s)^4 (tolerance 0.5 % and 5 mrad).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from rv_te_bench.core.orders import OrderSet
from rv_te_bench.errors import BagError, TeConfigError
from rv_te_bench.report import analysis
from rv_te_bench.report.analysis import analyze_bag, likely_source
from sim.units import arcmin_to_rad
from tests.report.synthetic_bags import (
    CRANK_PER_OUTPUT,
    MESH_LABELS,
    MESH_ORDERS,
    RATIO,
    Harmonic,
    te_of,
    varying_speed,
    write_bag,
)

MEAN = float(arcmin_to_rad(-0.15))
HARMONICS = (
    Harmonic(25.0, float(arcmin_to_rad(0.6)), 0.3),     # 1 f_w
    Harmonic(50.0, float(arcmin_to_rad(0.2)), -1.0),    # 2 f_w
    Harmonic(1.0, float(arcmin_to_rad(0.1)), 0.5),      # f_out
)
#: An RV unit whose largest line is a cycloid-pin mesh line (order 936): what a tooth-profile
#: change acts on (a crank line dominant withholds it: tests/report/test_advice_gate.py).
RV_HARMONICS = (Harmonic(936.0, float(arcmin_to_rad(0.8)), 0.2), *HARMONICS)


def _line(res: analysis.AnalysisResult, label: str) -> object:
    assert res.spectrum is not None
    return next(ln for ln in res.spectrum.lines if ln.label == label)


@pytest.fixture(scope='module')
def constant_bag(tmp_path_factory: pytest.TempPathFactory) -> tuple[object, object]:
    path = tmp_path_factory.mktemp('const') / 'bag'
    synth = write_bag(path, harmonics=HARMONICS, mean_rad=MEAN, duration_s=6.5)
    return path, synth


def test_statistics_match_written_te_and_closed_form(constant_bag: tuple) -> None:
    path, synth = constant_bag
    res = analyze_bag(path, with_advice=False)
    assert not res.partial
    assert res.gaps == ()
    st = res.cumulative
    te = synth.te_rad
    assert st.n_samples == te.size == 6500
    assert_allclose([st.pp_rad, st.amplitude_rad, st.mean_rad, st.std_rad],
                    [te.max() - te.min(), np.abs(te).max(), te.mean(), te.std()], rtol=1e-9)
    dense = te_of(np.linspace(0.0, 2 * math.pi, 200_001), MEAN, HARMONICS)
    assert st.pp_rad == pytest.approx(dense.max() - dense.min(), rel=5e-3)
    assert st.amplitude_rad == pytest.approx(np.abs(dense).max(), rel=5e-3)
    complete = res.complete_windows
    assert len(complete) == 3  # 6.5 s at 0.5 rev/s: 3 whole revolutions and a quarter
    for w in complete:
        assert w.stats.n_samples == 2000
        assert w.stats.mean_rad == pytest.approx(MEAN, abs=1e-12)


def test_spectrum_lines_constant_speed(constant_bag: tuple) -> None:
    path, _ = constant_bag
    res = analyze_bag(path, with_advice=False)
    spec = res.spectrum
    assert spec is not None
    assert spec.n_windows == 3
    assert 'mean of 3 complete windows' in spec.method
    assert spec.output_hz == pytest.approx(0.5, rel=1e-3)
    assert spec.crank_hz == pytest.approx(0.5 * CRANK_PER_OUTPUT, rel=1e-3)
    for h, label in zip(HARMONICS, ('1 f_w', '2 f_w', 'f_out'), strict=True):
        ln = _line(res, label)
        assert ln.output_order == h.output_order
        assert ln.amplitude_rad == pytest.approx(h.amplitude_rad, rel=1e-6)
        assert ln.phase_rad == pytest.approx(h.phase_rad, abs=1e-6)
        assert ln.frequency_hz == pytest.approx(0.5 * h.output_order, rel=1e-3)
    for label in ('3 f_w', 'f_w - f_out', 'f_w + f_out', MESH_LABELS[0]):
        assert _line(res, label).amplitude_rad < 1e-9 * HARMONICS[0].amplitude_rad + 1e-15
    assert res.dominant is not None
    assert res.dominant.line.label == '1 f_w'
    assert 'eccentricity' in res.dominant.likely_source


def test_spectrum_lines_varying_speed(tmp_path) -> None:
    path = tmp_path / 'bag'
    synth = write_bag(path, harmonics=HARMONICS, mean_rad=MEAN, duration_s=6.5,
                      theta_in_fn=varying_speed(0.5, 0.3, 0.7))
    res = analyze_bag(path, with_advice=False)
    te = synth.te_rad
    st = res.cumulative
    assert_allclose([st.pp_rad, st.mean_rad], [te.max() - te.min(), te.mean()], rtol=1e-9)
    assert len(res.complete_windows) >= 3
    for h, label in zip(HARMONICS, ('1 f_w', '2 f_w', 'f_out'), strict=True):
        ln = _line(res, label)
        assert ln.amplitude_rad == pytest.approx(h.amplitude_rad, rel=5e-3)
        assert ln.phase_rad == pytest.approx(h.phase_rad, abs=5e-3)
    # speed varies: the spread of the per-window speeds does not smear the lines
    assert _line(res, '3 f_w').amplitude_rad < 5e-3 * HARMONICS[0].amplitude_rad


def test_gap_is_reported_and_breaks_the_trace(tmp_path) -> None:
    path = tmp_path / 'bag'
    synth = write_bag(path, harmonics=HARMONICS, mean_rad=MEAN, duration_s=6.5,
                      drop_seqs=[30])
    res = analyze_bag(path, with_advice=False)
    assert [g.kind for g in res.gaps] == ['seq_jump']
    assert res.gaps[0].seq == 31
    assert res.cumulative.n_samples == synth.te_rad.size == 6400
    assert np.isnan(res.trace.te_rad).sum() == 1
    assert res.spectrum is not None  # whole revolutions after the gap still count
    assert _line(res, '1 f_w').amplitude_rad == pytest.approx(HARMONICS[0].amplitude_rad,
                                                             rel=1e-6)


def test_trace_thinning_keeps_every_stride_th_sample(tmp_path, monkeypatch) -> None:
    path = tmp_path / 'bag'
    synth = write_bag(path, harmonics=HARMONICS, duration_s=3.0)
    monkeypatch.setattr(analysis, 'MAX_TRACE_POINTS', 700)
    res = analyze_bag(path, with_advice=False)
    tr = res.trace
    assert tr.stride == 8  # 3000 samples: 700 -> halve at 701 kept (stride 2, 4, 8)
    assert tr.te_rad.size <= 700
    assert_allclose(tr.te_rad, synth.te_rad[::tr.stride], rtol=0, atol=1e-15)
    assert_allclose(tr.theta_out_rad, synth.theta_out_rad[::tr.stride], rtol=0, atol=0)


def test_no_bench_info_needs_ratio_and_crank_order(tmp_path) -> None:
    path = tmp_path / 'bag'
    write_bag(path, harmonics=HARMONICS, duration_s=4.5, with_info=False)
    with pytest.raises(TeConfigError, match=r'no BenchInfo.*--ratio and --crank-per-output'):
        analyze_bag(path)
    with pytest.raises(TeConfigError, match=r'pass --crank-per-output'):
        analyze_bag(path, gear_ratio=RATIO)
    res = analyze_bag(path, gear_ratio=RATIO, crank_per_output=CRANK_PER_OUTPUT)
    assert res.bench.source == 'cli'
    assert _line(res, '1 f_w').amplitude_rad == pytest.approx(HARMONICS[0].amplitude_rad,
                                                             rel=1e-6)
    assert 'no BenchInfo preset' in res.recommendation.reason


def test_missing_bag_and_empty_encoder_topic(tmp_path) -> None:
    with pytest.raises(BagError, match='no such bag'):
        analyze_bag(tmp_path / 'nope')
    path = tmp_path / 'info_only'
    write_bag(path, harmonics=HARMONICS, with_blocks=False)
    with pytest.raises(BagError, match='no topic of type rv_te_msgs/msg/EncoderBlock'):
        analyze_bag(path)


@pytest.mark.parametrize(('preset', 'reason'), [
    ('li2023-rv', 'has no compensation model'),
    ('no-such-preset', 'cannot be loaded'),
])
def test_no_recommendation_says_why(tmp_path, preset: str, reason: str) -> None:
    path = tmp_path / 'bag'
    write_bag(path, harmonics=HARMONICS, duration_s=2.5, preset=preset, reducer_type='rv')
    res = analyze_bag(path)
    assert not res.recommendation.available
    assert res.recommendation.reason.startswith('no recommendation available')
    assert reason in res.recommendation.reason


_ORDERS = OrderSet(gear_ratio=RATIO, crank_per_output=CRANK_PER_OUTPUT,
                   mesh_orders_out=MESH_ORDERS, mesh_labels=MESH_LABELS)


@pytest.mark.parametrize(('order', 'words'), [
    (25.0, 'once per crank revolution'),
    (1.0, 'output-wheel (carrier) eccentricity or pin-circle'),
    (24.0, 'sideband'),
    (26.0, 'sideband'),
    (50.0, '2x per crank revolution'),
    (1300.0, 'tooth profile / pitch error of the mesh 52 f_w'),
    (3.0, '3x per output revolution'),
    (12.5, 'not assigned'),
])
def test_likely_source(order: float, words: str) -> None:
    assert words in likely_source(order, _ORDERS, '2kv')


def test_rv_recommendation_wiring(tmp_path, monkeypatch) -> None:
    """The RV path hands the preset and the measured p-p to the compensation code.

    The compensation module is replaced by a recorder, so this checks the wiring only
    (the compensation maths has its own tests).
    """
    import sys
    import types

    from rv_te_bench.core.advice import Advice

    seen = {}

    def tooth_profile_advice(preset, measured_rad, *, te_metric):
        seen['preset'], seen['measured_rad'] = preset.name, measured_rad
        seen['te_metric'] = te_metric
        return Advice(method='tooth-profile', preset=preset.name, summary='fake',
                      te_metric=te_metric, te_before_rad=measured_rad,
                      te_after_rad=0.5 * measured_rad)

    fake = types.ModuleType('rv_te_bench.core.tooth_compensation')
    fake.tooth_profile_advice = tooth_profile_advice
    monkeypatch.setitem(sys.modules, 'rv_te_bench.core.tooth_compensation', fake)
    path = tmp_path / 'bag'
    synth = write_bag(path, harmonics=RV_HARMONICS, duration_s=2.5, preset='hu2020-rv',
                      reducer_type='rv', sample_rate_hz=4000.0, block_size=400)
    res = analyze_bag(path)
    te = synth.te_rad
    assert seen == {'preset': 'hu2020-rv', 'te_metric': 'pp',
                    'measured_rad': pytest.approx(te.max() - te.min(), rel=1e-12)}
    rec = res.recommendation
    assert rec.available
    assert rec.advice is not None and rec.advice.summary == 'fake'
    doc = res.to_json_dict()['recommendation']
    assert doc['advice']['te_after_arcmin'] == pytest.approx(
        0.5 * doc['advice']['te_before_arcmin'])


def test_rv_recommendation_from_the_real_compensation_code(tmp_path) -> None:
    path = tmp_path / 'bag'
    synth = write_bag(path, harmonics=RV_HARMONICS, duration_s=2.5, preset='hu2020-rv',
                      reducer_type='rv', sample_rate_hz=4000.0, block_size=400)
    rec = analyze_bag(path).recommendation
    assert rec.available, rec.reason
    assert rec.advice is not None
    assert rec.advice.method == 'tooth-profile'
    assert rec.advice.te_metric == 'pp'
    te = synth.te_rad
    assert rec.advice.te_before_rad == pytest.approx(te.max() - te.min(), rel=1e-12)
    assert len(rec.advice.modifications) == 3


def test_2kv_advice_withheld_when_the_model_does_not_fit(tmp_path) -> None:
    """A 2K-V bag whose TE is a sum of arbitrary harmonics, not eccentricity TE: the
    identification explains ~94 % of the TE variance (residual ~6.7" against a TE std of
    27"), so no re-assembly advice is given, and the reason says so with the numbers
    (issue #15: advice used to be printed on such a fit)."""
    path = tmp_path / 'bag'
    write_bag(path, harmonics=HARMONICS, duration_s=2.5, preset='wang2020-2kv')
    rec = analyze_bag(path).recommendation
    assert not rec.available
    assert rec.advice is None
    assert 'advice withheld' in rec.reason
    assert 'of the TE variance' in rec.reason and 'fit residual' in rec.reason


def _retained_bytes(path: object) -> tuple[int, analysis.AnalysisResult]:
    """Bytes still allocated (tracemalloc: Python and numpy) while the result is alive."""
    import gc
    import tracemalloc

    analyze_bag(path, with_advice=False)  # imports and caches are not what is measured
    gc.collect()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        res = analyze_bag(path, with_advice=False)
        gc.collect()
        return tracemalloc.get_traced_memory()[0] - base, res
    finally:
        tracemalloc.stop()


def test_memory_does_not_grow_with_the_number_of_windows(tmp_path) -> None:
    """Each window's per-bin spectrum (here ~20k bins, ~0.6 MB) is folded into the average
    and dropped: 16 windows retain about what 4 do (the old code kept ~7.7 MB more)."""
    sizes = {}
    for n_windows in (4, 16):
        path = tmp_path / f'bag{n_windows}'
        write_bag(path, harmonics=HARMONICS, mean_rad=MEAN, duration_s=2.0 * n_windows + 0.5,
                  sample_rate_hz=20_000.0, block_size=1000, chunk_size_bytes=1 << 20)
        sizes[n_windows], res = _retained_bytes(path)
        assert len(res.complete_windows) == n_windows
        assert all(w.spectrum is not None and w.spectrum.orders.size == 0
                   and w.spectrum.lines for w in res.complete_windows)
    assert sizes[16] - sizes[4] < 1_000_000, sizes


def test_running_average_equals_the_mean_of_the_window_spectra(constant_bag: tuple) -> None:
    """The incremental average against numpy's mean over every window's full spectrum."""
    from rv_te_bench.core.offline import analyze_blocks
    from rv_te_bench.core.stream_records import TeAnalysisConfig
    from rv_te_bench.io.bag_reader import read_encoder_blocks

    path, _ = constant_bag
    res = analyze_bag(path, with_advice=False)
    full = analyze_blocks(read_encoder_blocks(path), TeAnalysisConfig(orders=res.bench.orders))
    spectra = [w.spectrum for w in full.windows if w.complete and w.spectrum is not None]
    assert res.spectrum is not None
    assert len(spectra) == res.spectrum.n_windows == 3
    assert_allclose(res.spectrum.amplitude_rad,
                    np.mean([s.amplitude_rad for s in spectra], axis=0), rtol=1e-12, atol=1e-18)
    assert_allclose(res.spectrum.orders, spectra[0].orders, rtol=0, atol=0)
    for k, line in enumerate(res.spectrum.lines):
        amps = [s.lines[k].amplitude_rad for s in spectra]
        phasor = np.mean([a * np.exp(1j * s.lines[k].phase_rad) for a, s in zip(amps, spectra,
                                                                                strict=True)])
        assert line.label == spectra[0].lines[k].label
        assert_allclose(line.amplitude_rad, np.mean(amps), rtol=1e-12, atol=1e-18)
        if abs(phasor) > 1e-12:
            assert_allclose(line.phase_rad, np.angle(phasor), atol=1e-9)
