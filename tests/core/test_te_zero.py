"""core.te_zero: the TE's zero is independent of the encoders' zeros (issue 33 s.1)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rv_te_bench.core.stream_records import EncoderBatch, EncoderBlockData
from rv_te_bench.core.te_zero import EncoderZero, TeZero, wrap_turn_rad
from rv_te_bench.errors import TeConfigError

RATIO = 79.0


def _block(seq: int, th_in: np.ndarray, th_out: np.ndarray) -> EncoderBlockData:
    return EncoderBlockData(seq, 0.0, 1000.0, np.arange(th_in.size) / 1000.0, th_in, th_out)


def _te(z: TeZero, th_in: np.ndarray, th_out: np.ndarray) -> np.ndarray:
    b = z.apply(_block(0, th_in, th_out))
    return b.theta_out_rad - b.theta_in_rad / RATIO


@given(off_out=st.floats(-20.0, 20.0), off_in=st.floats(-1e4, 1e4))
def test_first_sample_reference_ignores_both_zeros(off_out: float, off_in: float) -> None:
    phi = np.linspace(0.0, 2 * math.pi, 500, endpoint=False)
    te = 1e-4 * np.cos(phi + 0.3) + 3e-5 * np.sin(25 * phi)
    th_in = phi * RATIO
    a = _te(TeZero('first-sample', gear_ratio=RATIO, declared=None), th_in, phi + te)
    b = _te(TeZero('first-sample', gear_ratio=RATIO, declared=None), th_in + off_in,
            phi + te + off_out)
    np.testing.assert_allclose(a, te - te[0], atol=1e-12)
    np.testing.assert_allclose(b, te - te[0], atol=1e-9)


@pytest.mark.parametrize(('offset_deg', 'turns'), [(359.998, 1), (-359.998, -1), (720.5, 2),
                                                    (123.4, 0)])
def test_declared_zero_removes_whole_output_turns(offset_deg: float, turns: int) -> None:
    """No zeros declared, 'encoders': only whole output turns go (359.998 -> -0.002 deg)."""
    th_in = np.array([0.0, 0.1, 0.2])
    th_out = th_in / RATIO + math.radians(offset_deg)
    z = TeZero('encoders', gear_ratio=RATIO, declared=None)
    te = _te(z, th_in, th_out)
    assert z.reference.whole_turns == turns
    np.testing.assert_allclose(te, wrap_turn_rad(math.radians(offset_deg)), atol=1e-12)


def test_declared_zero_offsets() -> None:
    th_in = np.array([5.0, 5.1])
    th_out = th_in / RATIO + math.radians(123.4) + 2e-5
    z = TeZero('auto', gear_ratio=RATIO,
               declared=EncoderZero(input_rad=5.0, output_rad=math.radians(123.4),
                                    source='step'))
    te = _te(z, th_in, th_out)
    np.testing.assert_allclose(te, 2e-5 + 5.0 / RATIO, atol=1e-12)
    assert z.reference.method == 'encoders' and z.reference.whole_turns == 0


def test_batch_equals_blocks_and_latches_on_the_first_clean_sample() -> None:
    th_in = np.linspace(0.0, 10.0, 300)
    th_out = th_in / RATIO + 2.0
    th_out[:5] = np.nan      # block 0 is not clean (the analyzer drops it): latch on block 1
    blocks = [_block(k, th_in[k * 100:(k + 1) * 100], th_out[k * 100:(k + 1) * 100])
              for k in range(3)]
    z1 = TeZero('first-sample', gear_ratio=RATIO, declared=None)
    one = np.concatenate([z1.apply(b).theta_out_rad for b in blocks])
    z2 = TeZero('first-sample', gear_ratio=RATIO, declared=None)
    batch = z2.apply_batch(EncoderBatch.from_blocks(blocks))
    np.testing.assert_array_equal(one, batch.theta_out_rad)
    assert z1.reference == z2.reference
    assert z1.reference.source == 'block seq 1, sample 0'
    assert z1.reference.removed_rad == pytest.approx(2.0, abs=1e-12)
    assert np.max(np.abs(one[100:] - th_in[100:] / RATIO)) < 1e-12


def test_bad_mode_and_zero() -> None:
    with pytest.raises(TeConfigError, match="got 'zero'"):
        TeZero('zero', gear_ratio=RATIO, declared=None)
    with pytest.raises(TeConfigError, match='output_rad'):
        EncoderZero(output_rad=float('nan'))
