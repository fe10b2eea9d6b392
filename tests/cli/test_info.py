"""``rv-te info BAG``: the first look at a bag (issue 33 s.6), as ``ros2 bag info`` gives it.

Bags written by rosbags (tests.unit_bags) with a unit serial in the session metadata and a
recorder that joined late; a synthetic bag with two blocks left out. Expected counts are the
arrays written here.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import numpy as np
import pytest

from rv_te_bench.cli.main import main
from tests.report.synthetic_bags import Harmonic, write_bag
from tests.unit_bags import write_unit_bag

if TYPE_CHECKING:
    from pathlib import Path

RATE_HZ = 1000.0


def test_info_of_a_rosbags_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    n = 2500                                      # 25 blocks of 100 samples, 2.5 s
    theta_in = np.linspace(0.0, 2 * np.pi * 3, n)
    bag = write_unit_bag(tmp_path / 'run', theta_in, theta_in / 79.0, rate_hz=RATE_HZ,
                         block=100, custom_data={'unit_serial': 'SN-77', 'operator': 'kim'},
                         first_seq=4)
    assert main(['info', str(bag), '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc['topics']['/bench/encoders']['count'] == 25
    assert doc['topics']['/bench/info']['count'] == 1
    assert doc['topics']['/bench/encoders']['type'] == 'rv_te_msgs/msg/EncoderBlock'
    assert doc['duration_s'] == pytest.approx(2.4, abs=2e-3)   # first to last message stamp
    assert doc['bench']['gear_ratio'] == 79.0 and doc['bench']['sample_rate_hz'] == RATE_HZ
    assert (doc['unit']['serial'], doc['unit']['operator']) == ('SN-77', 'kim')
    enc = doc['encoders']
    assert (enc['blocks'], enc['samples'], enc['first_seq']) == (25, n, 4)
    assert enc['blocks_missing'] == 4 and enc['gaps'] == []     # joined at seq 4
    # the text form: one line each, nothing recorded anywhere
    assert main(['info', str(bag)]) == 0
    out = capsys.readouterr().out
    assert 'serial SN-77' in out and 'i = 79' in out and '/bench/encoders' in out
    assert '25 blocks, 2500 samples' in out


def test_info_lists_the_gaps(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_bag(tmp_path / 'gappy', harmonics=[Harmonic(25.0, 1e-4, 0.0)], duration_s=3.0,
              drop_seqs=(7, 8, 20))
    assert main(['info', str(tmp_path / 'gappy'), '--json']) == 0
    enc = json.loads(capsys.readouterr().out)['encoders']
    assert enc['blocks'] == 27 and enc['blocks_missing'] == 3
    assert [(g['after_seq'], g['next_seq']) for g in enc['gaps']] == [(6, 9), (19, 21)]


def test_info_of_no_bag_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['info', str(tmp_path / 'nothing')]) == 1
    err = capsys.readouterr().err
    assert err.startswith('ERROR: ') and len(err.strip().splitlines()) == 1
