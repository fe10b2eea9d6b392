"""Issue #15 item 5: a recorder that starts after the bench loses the first blocks; the
analysis said "gaps: none". A bench numbers its EncoderBlocks from 0, so a first seq above 0
is a reported leading loss (count and seq range) in the text, the HTML report and the JSON,
and the same in the streaming core a late TE node runs.

The bags are written by ``rosbags`` (tests/unit_bags.py), the unit by the independent
reference model (tests/wang2020_reference.py).
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import numpy as np
import pytest

from rv_te_bench.cli.main import main
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.stream import StreamingTeAnalyzer
from rv_te_bench.core.stream_records import EncoderBlockData, TeAnalysisConfig
from tests import wang2020_reference as ref
from tests.unit_bags import unit_bag

if TYPE_CHECKING:
    from pathlib import Path

RATE_HZ = 1000.0
ORDERS = OrderSet(gear_ratio=79.0, crank_per_output=25.0, n_crank_harmonics=3,
                  mesh_orders_out=(250.0,), mesh_labels=('mesh',))


@pytest.fixture(scope='module')
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[int, Path]:
    d = tmp_path_factory.mktemp('late')
    out = {}
    for first in (0, 34):
        rng = np.random.default_rng(15)   # the same unit and record in both bags
        out[first] = unit_bag(d / f'from{first}', ref.random_unit(rng), rng, rate_hz=RATE_HZ,
                              duration_s=17.0, first_seq=first)
    return out


def test_late_recording_is_a_reported_leading_loss(bags: dict[int, Path], tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['analyze', str(bags[34]), '--no-advice', '--no-db',
                 '--report', str(tmp_path / 'rep')]) == 0
    text = capsys.readouterr().out
    assert 'gaps: none' not in text
    assert 'leading_loss at seq 34: the first 34 block(s) (seq 0-33) are missing' in text
    html = (tmp_path / 'rep' / 'report.html').read_text(encoding='utf-8')
    assert 'the first 34 block(s) (seq 0-33) are missing' in html
    assert main(['analyze', str(bags[34]), '--no-advice', '--no-db', '--json', '--quiet']) == 0
    (res,) = json.loads(capsys.readouterr().out)['bags']
    assert [(g['kind'], g['seq']) for g in res['gaps']] == [('leading_loss', 34)]


def test_a_recording_from_seq_0_has_no_gap(bags: dict[int, Path],
                                           capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['analyze', str(bags[0]), '--no-advice', '--no-db']) == 0
    assert 'gaps: none' in capsys.readouterr().out


def _blocks(first: int, n: int) -> list[EncoderBlockData]:
    theta_in = np.linspace(0.0, 3.0, 100 * n)
    return [EncoderBlockData(seq=first + k, stamp_s=k * 100 / RATE_HZ, sample_rate_hz=RATE_HZ,
                             time_offset_s=np.arange(100) / RATE_HZ,
                             theta_in_rad=theta_in[100 * k:100 * (k + 1)],
                             theta_out_rad=theta_in[100 * k:100 * (k + 1)] / 79.0)
            for k in range(n)]


@pytest.mark.parametrize('first', [0, 1, 7])
def test_streaming_core_block_by_block_and_batched(first: int) -> None:
    """A TE node that joins late (push) and the offline batches (push_batch) agree."""
    from rv_te_bench.core.stream_records import EncoderBatch

    cfg = TeAnalysisConfig(orders=ORDERS)
    one = StreamingTeAnalyzer(cfg)
    kinds = [g.kind for b in _blocks(first, 5) for g in one.push(b).gaps]
    batched = StreamingTeAnalyzer(cfg)
    upd = batched.push_batch(EncoderBatch.from_blocks(_blocks(first, 5)))
    expected = ['leading_loss'] if first else []
    assert kinds == [g.kind for g in upd.gaps] == expected
    assert one.counters['leading_loss'] == batched.counters['leading_loss'] == int(first > 0)
