"""The importers' drop-out finder and per-channel unwrapping (issue #32 s.1), on arrays whose
truth is closed-form: a single-turn channel's whole turns across a drop-out come from the
speed before and after when one candidate is within half a turn of both predictions, a
multi-turn counter keeps its recorded advance, and an ambiguous drop-out splits the record.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.io.importers._common import RawChunk
from rv_te_bench.io.importers._convert import ChunkConverter
from rv_te_bench.io.importers._turns import TurnStitcher

TWO_PI = 2 * math.pi
RATE = 1000.0


def converter(rate_hz: float | None = RATE) -> ChunkConverter:
    return ChunkConverter(origin='f.csv', labels={'time': 't', 'in': 'a', 'out': 'b'},
                          locate=lambda i: f'line {i + 2}', k_in=1.0, k_out=1.0,
                          time_scale_s=1.0, rate_hz=rate_hz, torque_scale_nm=1.0)


def run(t: np.ndarray, a: np.ndarray, b: np.ndarray, *, turns_in: str = 'auto',
        turns_out: str = 'auto', chunk: int = 997) -> tuple[list, TurnStitcher]:
    conv = converter()
    st = TurnStitcher(turns_in=turns_in, turns_out=turns_out, rate_hz=RATE)  # type: ignore[arg-type]
    pieces = []
    for s in range(0, t.size, chunk):
        raw = RawChunk(first=s, time=t[s:s + chunk], theta_in=a[s:s + chunk],
                       theta_out=b[s:s + chunk])
        pieces += st.push(conv(raw))
    pieces += st.finish()
    return pieces, st


def joined(pieces: list, field: str) -> np.ndarray:
    return np.concatenate([getattr(p, field) for p in pieces])


@pytest.mark.parametrize('gap_s', [0.025, 0.3, 1.0, 10.0, 37.3])
@pytest.mark.parametrize('rps', [0.3165, -0.4, 2.7])
def test_single_turn_turns_from_the_speed(gap_s: float, rps: float) -> None:
    """A single-turn encoder at a steady speed (either direction), a drop-out of 25 ms to
    37 s: the unwrapped angle after it equals the true multi-turn angle (to rounding), and
    the reported advance is the true one."""
    t = np.arange(0, 10.0 + gap_s, 1 / RATE)
    t = t[(t < 5.0) | (t >= 5.0 + gap_s)]
    truth = 0.7 + TWO_PI * rps * t
    pieces, st = run(t, truth.copy(), np.mod(truth, TWO_PI))
    (gap,) = st.gaps
    assert gap.how_out == 'speed' and not gap.split
    assert gap.how_in == 'counter'   # the input (= truth here) spans more than a turn
    assert gap.advance_out_rev == pytest.approx(rps * (gap_s + 1 / RATE), abs=1e-9)
    out = joined(pieces, 'theta_out_rad')
    np.testing.assert_allclose(out - out[0], truth - truth[0], rtol=0, atol=1e-9)
    assert [p.gap is not None for p in pieces].count(True) == 1


def test_a_wrap_inside_the_dropout_before_any_wrap_was_seen() -> None:
    """auto: 40 ms into the record (no wrap seen yet, readings within one turn) the output
    wraps during a 25 ms drop-out; the recorded step (-0.99 turn) contradicts the speed,
    the speed's candidate (+0.008 turn) is taken. Told it is a counter (--no-unwrap-out),
    the recorded step is kept."""
    t = np.arange(0, 1.0, 1 / RATE)
    t = t[(t < 0.040) | (t >= 0.065)]
    truth = TWO_PI - 0.1 + 2.0 * t          # 2 rad/s: crosses 2 pi at t = 0.05 s
    wrapped = np.mod(truth, TWO_PI)
    pieces, st = run(t, truth.copy(), wrapped)
    (gap,) = st.gaps
    assert (gap.how_out, round(gap.advance_out_rev * TWO_PI, 9)) == ('speed', 0.052)
    np.testing.assert_allclose(joined(pieces, 'theta_out_rad'), truth, rtol=0, atol=1e-12)
    pieces, st = run(t, truth.copy(), wrapped, turns_out='multi')
    assert st.gaps[0].how_out == 'counter'
    assert st.gaps[0].advance_out_rev * TWO_PI == pytest.approx(0.052 - TWO_PI, abs=1e-9)


def test_ambiguous_turns_split_the_record() -> None:
    """The drive slowed from 1500 to 600 rpm during a 10 s drop-out: the predictions from
    before (3.17 rev of the output) and after (1.27 rev) are more than a turn apart, so
    no candidate is within half a turn of both: the record is split, nothing guessed."""
    ratio = 79.0
    w1, w2 = TWO_PI * 25.0, TWO_PI * 10.0    # input rad/s
    t1 = np.arange(0, 8.0, 1 / RATE)
    t2 = np.arange(18.0, 26.0, 1 / RATE)
    th_in = np.concatenate([w1 * t1, w1 * 8.0 + (w1 + w2) / 2 * 10.0 + w2 * (t2 - 18.0)])
    t = np.concatenate([t1, t2])
    th_out = th_in / ratio
    pieces, st = run(t, th_in, np.mod(th_out, TWO_PI))
    (gap,) = st.gaps
    assert gap.split and gap.how_out == 'ambiguous' and gap.how_in == 'counter'
    assert math.isnan(gap.advance_out_rev)
    assert gap.advance_in_rev == pytest.approx((th_in[8000] - th_in[7999]) / TWO_PI)
    starts = [k for k, p in enumerate(pieces) if p.new_segment]
    assert len(starts) == 1 and pieces[starts[0]].t_s[0] == pytest.approx(18.0)
    # within each segment the output is unwrapped continuously (TE = 0 up to a constant)
    for seg in (pieces[:starts[0]], pieces[starts[0]:]):
        te = joined(seg, 'theta_out_rad') - joined(seg, 'theta_in_rad') / ratio
        assert np.ptp(te) < 1e-9


def test_counter_keeps_its_recorded_advance() -> None:
    """A multi-turn counter's advance across a drop-out is what it counted, even where
    the speed predicts another (the drive stopped during the drop-out)."""
    t = np.concatenate([np.arange(0, 2.0, 1 / RATE), np.arange(5.0, 7.0, 1 / RATE)])
    th = np.where(t < 2.0, 50.0 * t, 50.0 * 2.0 + 50.0 * (t - 5.0))   # stood still 3 s
    _, st = run(t, th, th * 0.01, turns_in='multi')
    assert st.gaps[0].how_in == 'counter'
    assert st.gaps[0].advance_in_rev * TWO_PI == pytest.approx(50.0 / RATE, abs=1e-9)


def test_dropout_reasons_counts_and_where() -> None:
    """Rows missing (a time step), NaN rows, a row going back in time, NaN at the start and
    at the end: each break once, with its reason, samples and the line it begins at; the
    chunk boundaries (chunk=7) cut through them."""
    t = np.arange(60) / RATE
    a = 0.01 * np.arange(60.0)
    b = 0.001 * np.arange(60.0)
    t[10:13] = np.nan                       # NaN time: 3 dropped
    a[20] = np.nan                          # NaN angle: 1 dropped
    t[30] = t[25]                           # back in time: 1 dropped
    keep = np.ones(60, dtype=bool)
    keep[40:45] = False                     # rows missing: 5
    a[0:2] = np.nan                         # leading
    b[58:] = np.nan                         # trailing
    t, a, b = t[keep], a[keep], b[keep]
    conv = converter()
    st = TurnStitcher(turns_in='auto', turns_out='auto', rate_hz=RATE)
    for s in range(0, t.size, 7):
        st.push(conv(RawChunk(first=s, time=t[s:s + 7], theta_in=a[s:s + 7],
                              theta_out=b[s:s + 7])))
    st.finish()
    got = [(g.reason, g.samples_dropped, g.samples_missing, g.where,
            round(g.t_before_s * RATE), round(g.t_after_s * RATE)) for g in st.gaps]
    # file line = sample + 2; after the 5 missing rows the file index is 5 less
    assert got == [('non_finite', 3, 0, 'line 12', 9, 13),
                   ('non_finite', 1, 0, 'line 22', 19, 21),
                   ('time_backwards', 1, 0, 'line 32', 29, 31),
                   ('time_step', 0, 5, 'line 42', 39, 45)]
    assert conv.leading_dropped == 2
    assert conv.finish() == (2, 'line 55')
    assert conv.samples == 60 - 5 - 3 - 1 - 1 - 2 - 2


def test_rate_is_the_median_step() -> None:
    """Without a stated rate the period is the median step of the first chunk, which its
    drop-outs do not move."""
    t = np.arange(0, 1.0, 1 / 2500)
    t = np.concatenate([t[:100], t[400:]])
    conv = converter(rate_hz=None)
    conv(RawChunk(first=0, time=t, theta_in=t, theta_out=t))
    assert conv.rate_hz == pytest.approx(2500.0)
