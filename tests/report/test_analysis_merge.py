"""The offline analysis reads a bag's chunks merged into larger batches (issue 41: less
work per batch); that must change nothing. The reference is the same analysis with every
chunk its own batch (MERGE_SAMPLES planted at 1), on a bag written by rosbags (1 MiB
chunks) of a 2K-V unit from tests/wang2020_reference.py, with advice (the angle fold of
every sample, whose noise estimate depends on where the record is cut), on both paths."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rv_te_bench.io import bag_reader
from tests import wang2020_reference as ref
from tests.report.analysis_doc import analysis_doc
from tests.unit_bags import unit_bag


@pytest.mark.parametrize('helper', ['0', '1'])
def test_merged_batches_give_the_same_analysis(tmp_path: Path, helper: str,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv('RV_TE_READ_AHEAD', helper)
    rng = np.random.default_rng(41)
    bag = unit_bag(tmp_path / 'unit', ref.random_unit(rng), rng,
                   duration_s=2 * 60.0 * ref.RATIO / 300.0)
    merged = [i.n_samples for i in bag_reader.read_encoder_batches(bag, merge=True)]
    chunkwise = [i.n_samples for i in bag_reader.read_encoder_batches(bag)]
    assert len(merged) < len(chunkwise)          # the bag's chunks were merged
    got = analysis_doc(bag)
    monkeypatch.setattr(bag_reader, 'MERGE_SAMPLES', 1)   # each chunk its own batch
    assert [i.n_samples for i in bag_reader.read_encoder_batches(bag, merge=True)] \
        == chunkwise
    want = analysis_doc(bag)
    assert '"identification"' in want
    assert got == want
