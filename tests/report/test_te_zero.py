"""The TE's zero (issue 33 s.1): encoder zeros, the first sample, whole output turns.

The bags are written by rosbags (tests.unit_bags), the encoder data by the paper's equations
written out in the tests (tests.wang2020_reference); the expected statistics are computed
here from those arrays, not by the suite.
"""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING

import numpy as np
import pytest
import yaml

from tests import wang2020_reference as ref
from tests.unit_bags import write_unit_bag

if TYPE_CHECKING:
    from pathlib import Path

RATE_HZ = 1000.0
REVS = 2.05                                 # two whole output revolutions and a bit
N = round(REVS * 60.0 / 300.0 * ref.RATIO * RATE_HZ)
OFFSETS_DEG = (0.0, 123.4, 359.998)


def _record() -> tuple[np.ndarray, np.ndarray]:
    """(theta_in, theta_out) [rad] of the Wang 2020 Table 2 unit, encoders zeroed."""
    rng = np.random.default_rng(33)
    return ref.encoder_record(ref.table2_unit(), rng, n_samples=N, revolutions=REVS,
                              noise_arcsec=0.2, theta_in_start_rad=0.0)


def _bag(tmp_path: Path, name: str, offset_deg: float, **kwargs: object) -> Path:
    th_in, th_out = _record()
    return write_unit_bag(tmp_path / name, th_in, th_out + math.radians(offset_deg),
                          rate_hz=RATE_HZ, **kwargs)  # type: ignore[arg-type]


def _line(res: object, label: str) -> float:
    (ln,) = [x for x in res.spectrum.lines if x.label == label]  # type: ignore[attr-defined]
    return float(ln.amplitude_rad)


def test_mean_amplitude_and_lines_do_not_depend_on_the_encoder_zero(tmp_path: Path) -> None:
    """Output encoder 123.4 deg and 359.998 deg off (a rosbags bag, no declared zeros):
    the same mean, amplitude, p-p and once-per-revolution line as zeroed encoders; today's
    main gave a mean of 7403.9' and 21599.7' (the offset itself)."""
    from rv_te_bench.report.analysis import analyze_bag

    th_in, th_out = _record()
    te = th_out - th_in / ref.RATIO                 # Eq. 22 computed here
    expect = te - te[0]                             # referred to the first sample
    results = [analyze_bag(_bag(tmp_path, f'off{k}', off), with_advice=False)
               for k, off in enumerate(OFFSETS_DEG)]
    for res in results:
        st = res.cumulative
        assert st.mean_rad == pytest.approx(expect.mean(), abs=1e-10)
        assert st.amplitude_rad == pytest.approx(np.abs(expect).max(), abs=1e-10)
        assert st.pp_rad == pytest.approx(np.ptp(te), abs=1e-10)
        assert res.te_reference is not None and res.te_reference.method == 'first-sample'
    base = results[0]
    for res in results[1:]:
        assert res.cumulative.mean_rad == pytest.approx(base.cumulative.mean_rad, abs=1e-10)
        for label in ('f_out', '1 f_w', 'f_w - f_out'):
            assert _line(res, label) == pytest.approx(_line(base, label), abs=1e-10)
        for w, w0 in zip(res.windows, base.windows, strict=True):
            assert w.stats.mean_rad == pytest.approx(w0.stats.mean_rad, abs=1e-10)
            assert w.stats.amplitude_rad == pytest.approx(w0.stats.amplitude_rad, abs=1e-10)
    # the removed offset is stated wrap-aware: 359.998 deg is -0.002 deg and one turn
    r = results[2].te_reference
    assert r.removed_within_turn_rad == pytest.approx(math.radians(-0.002) + te[0], abs=1e-9)
    assert r.whole_turns == 1
    assert '-0.002' in f'{math.degrees(r.removed_within_turn_rad):+.3f}'


def test_declared_encoder_zeros_keep_the_absolute_te(tmp_path: Path) -> None:
    """A bench that declares its output encoder's zero (123.4 deg): the TE is referred to
    it, so the mean is the reducer's own (the model's mean, not relative to a sample)."""
    from rv_te_bench.report.analysis import analyze_bag

    th_in, th_out = _record()
    te = th_out - th_in / ref.RATIO
    declared = yaml.safe_dump({'encoder_zero': {
        'input_rad': 0.0, 'output_rad': math.radians(123.4), 'source': 'zeroing step Z-7'}})
    res = analyze_bag(_bag(tmp_path, 'declared', 123.4, parameters_yaml=declared),
                      with_advice=False)
    assert res.te_reference.method == 'encoders'
    assert 'zeroing step Z-7' in res.te_reference.describe()
    assert res.cumulative.mean_rad == pytest.approx(te.mean(), abs=1e-10)
    assert res.cumulative.amplitude_rad == pytest.approx(np.abs(te).max(), abs=1e-10)


def test_encoder_zeros_remove_whole_output_turns(tmp_path: Path) -> None:
    """--te-zero encoders on a single-turn output encoder that starts at 359.998 deg: the
    TE is 0.002 deg below the zeroed one, not a turn above (the mean is not 6.283 rad)."""
    from rv_te_bench.report.analysis import analyze_bag

    th_in, th_out = _record()
    te = th_out - th_in / ref.RATIO
    res = analyze_bag(_bag(tmp_path, 'turn', 359.998), with_advice=False, te_zero='encoders')
    assert res.te_reference.method == 'encoders'
    assert res.te_reference.whole_turns == 1
    assert res.cumulative.mean_rad == pytest.approx(te.mean() + math.radians(-0.002),
                                                    abs=1e-10)


def test_the_report_states_the_zero(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """rv-te analyze: the text, the JSON and the HTML name the reference used."""
    from rv_te_bench.cli.main import main

    bag = _bag(tmp_path, 'rep', 123.4)
    assert main(['analyze', str(bag), '--no-advice', '--no-db', '--quiet', '--json',
                 '--report', str(tmp_path / 'rep_report')]) == 0
    doc = json.loads(capsys.readouterr().out)
    (one,) = doc['bags']
    zero = one['te_reference']
    assert zero['method'] == 'first-sample'
    assert zero['removed_within_turn_deg'] == pytest.approx(123.4, abs=1e-3)
    html = (tmp_path / 'rep_report' / 'report.html').read_text(encoding='utf-8')
    assert 'TE referred to its first clean sample' in html
    assert main(['analyze', str(bag), '--no-advice', '--no-db', '--quiet']) == 0
    assert 'zero: TE referred to its first clean sample' in capsys.readouterr().out
