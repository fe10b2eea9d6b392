"""``rv-te optimize-phases`` and ``rv-te identify``: output, exit codes, one-line errors.

The parsers are built from the modules' ``register`` (the contract with cli/main.py). The
identify bags are written here with BagWriter from messages serialised by the rosbags
typestore, holding a TE synthesised with sim.wang2020 (Table 2 unit) plus 0.3" noise.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import pytest

import rv_te_bench.io.bag_reader  # noqa: F401 - in the tree: an import error must fail
from rv_te_bench.cli import identify, optimize_phases
from rv_te_bench.io import bag_writer, msgdefs
from rv_te_bench.io._legacy_msgs import added_field_defaults
from sim import presets
from sim import wang2020 as wang

RATIO = 79.0
RATE_HZ = 400.0
T0_NS = 1_700_000_000_000_000_000


def _run(module, name: str, argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog='rv-te')
    module.register(parser.add_subparsers())
    args = parser.parse_args([name, *argv])
    return args.func(args)


def _one_error_line(capsys: pytest.CaptureFixture[str], needle: str) -> None:
    captured = capsys.readouterr()
    assert captured.out == ''                     # nothing written half-way
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith('ERROR: ')
    assert needle in lines[0]


# ---------------------------------------------------------------- optimize-phases


def test_optimize_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert _run(optimize_phases, 'optimize-phases',
                ['wang2020-2kv', '--step-deg', '30', '--quiet', '--json']) == 0
    data = json.loads(capsys.readouterr().out)
    assert data['preset'] == 'wang2020-2kv'
    assert data['n_combinations'] == 13**4
    assert data['objective_after_arcmin'] < data['objective_before_arcmin']
    # the before-phases are Table 2's
    np.testing.assert_allclose(data['phases_before_deg'], [90.0, 180.0, -135.0, 90.0],
                               atol=1e-9)
    # grid phases print as written, not with the rad round trip's noise (120.00000000000001)
    assert all(p == round(p) and round(p) % 30 == 0 for p in data['phases_after_deg'])
    assert data['phases_before_deg'] == [90.0, 180.0, -135.0, 90.0]
    adv = data['advice']
    assert adv['method'] == 'assembly-phases'
    assert adv['te_metric'] == 'amplitude'
    assert [m['symbol'] for m in adv['modifications']] == ['theta_p1', 'theta_p2', 'theta_g',
                                                           'theta_ot']
    assert {r['case'] for r in data['table']} == {'NLTE', '30 Nm STE', '100 Nm STE',
                                                  '300 Nm STE'}


@pytest.mark.slow
def test_optimize_paper_grid_text_with_progress(capsys: pytest.CaptureFixture[str]) -> None:
    """Default 10 deg grid: the paper's optimum in the text table, progress to 100 %."""
    assert _run(optimize_phases, 'optimize-phases', ['wang2020-2kv']) == 0
    captured = capsys.readouterr()
    rows = {line.split()[0]: line.split()[1:] for line in captured.out.splitlines()
            if line.startswith('theta_')}
    assert [float(rows[k][1]) for k in ('theta_p1', 'theta_p2', 'theta_g', 'theta_ot')] == [
        -70.0, 120.0, 110.0, 40.0]
    assert '100%' in captured.err
    assert 'ERROR' not in captured.err


@pytest.mark.parametrize(('argv', 'needle'), [
    (['wang2020-2kv', '--step-deg', '0'], '--step-deg must be finite, > 0'),
    (['wang2020-2kv', '--step-deg', '-5'], '--step-deg must be finite, > 0'),
    (['wang2020-2kv', '--step-deg', 'nan'], '--step-deg must be finite'),
    (['wang2020-2kv', '--refine', '--refine-tol-deg', '0'], '--refine-tol-deg'),
    (['wang2020-2kv', '--set', 'nokey=1'], "no key 'nokey'"),
    (['wang2020-2kv', '--set', 'eccentricity.e_p1_m=-1e-5'], 'e_p1'),
    (['no-such-preset'], "unknown preset 'no-such-preset'"),
    (['hu2020-rv'], 'need a wang2020-2kv preset'),
    (['wang2020-2kv', '--loads-nm', '30,nan'], 'loads_nm'),
])
def test_optimize_errors(argv: list[str], needle: str,
                         capsys: pytest.CaptureFixture[str]) -> None:
    assert _run(optimize_phases, 'optimize-phases', [*argv, '--quiet']) == 1
    _one_error_line(capsys, needle)


# ---------------------------------------------------------------- identify


def _write_bag(path: Path, theta_in: np.ndarray, theta_out: np.ndarray, *,
               block: int = 500, info: bool = True, encoders: bool = True) -> Path:
    store = msgdefs.rv_te_typestore()
    header = store.types['std_msgs/msg/Header']
    stamp = store.types['builtin_interfaces/msg/Time']

    def hdr(t_ns: int):
        return header(stamp=stamp(sec=t_ns // 10**9, nanosec=t_ns % 10**9), frame_id='b0')

    with bag_writer.BagWriter(path) as writer:
        if info:
            writer.add_topic('/bench/info', msgdefs.BENCH_INFO)
            bi = store.types[msgdefs.BENCH_INFO](
                header=hdr(T0_NS), bench_id='b0', preset='wang2020-2kv', reducer_type='2kv',
                gear_ratio=RATIO, crank_per_input=-25 / RATIO, crank_rel_per_input=-26 / RATIO,
                mesh_orders=np.array([1300.0]), mesh_labels=['stage-2 mesh (52 f_w)'],
                encoder_in_model='heidenhain-ron886', encoder_out_model='heidenhain-ron886',
                encoder_in_resolution_rad=1.745e-7, encoder_out_resolution_rad=1.745e-7,
                sample_rate_hz=RATE_HZ, block_size=block, parameters_yaml='',
                **added_field_defaults(msgdefs.BENCH_INFO))
            writer.write('/bench/info', T0_NS,
                         bytes(store.serialize_cdr(bi, msgdefs.BENCH_INFO)))
        if encoders:
            writer.add_topic('/bench/encoders', msgdefs.ENCODER_BLOCK)
            eb = store.types[msgdefs.ENCODER_BLOCK]
            for seq, s in enumerate(range(0, theta_in.size, block)):
                t_ns = T0_NS + round(s / RATE_HZ * 1e9)
                msg = eb(header=hdr(t_ns), seq=seq, sample_rate_hz=RATE_HZ,
                         time_offset_s=np.arange(min(block, theta_in.size - s)) / RATE_HZ,
                         theta_in_rad=theta_in[s:s + block], theta_out_rad=theta_out[s:s + block],
                         torque_out_nm=np.zeros(0),
                         **added_field_defaults(msgdefs.ENCODER_BLOCK))
                writer.write('/bench/encoders', t_ns + 1,
                             bytes(store.serialize_cdr(msg, msgdefs.ENCODER_BLOCK)))
    return path


@pytest.fixture(scope='module')
def session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One output revolution (15.8 s at 300 rpm) of the Table 2 unit, 0.3" noise per shaft."""
    params = wang.Wang2kvParams.from_preset(presets.load_preset('wang2020-2kv'))
    rng = np.random.default_rng(11)
    n = int(RATE_HZ * 15.8)
    theta_in = np.arange(n) * (RATIO * 2 * math.pi / n)
    phi = theta_in / RATIO
    sigma = math.radians(0.3 / 3600)
    theta_out = phi + wang.nlte_rad(phi, params) + sigma * rng.standard_normal(n)
    theta_in = theta_in + sigma * rng.standard_normal(n)
    return _write_bag(tmp_path_factory.mktemp('bags') / 'session', theta_in, theta_out)


def test_identify_json(session: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The Table 2 unit is recovered (e_ot 10 um at 90 deg; with the preset's part
    magnitudes theta_p1/p2/g = 90/180/-135 deg) within 5 % / 3 deg, and the advice turns
    it towards the paper's grid optimum region (S reduced by > 40 %)."""
    assert _run(identify, 'identify', [str(session), '--json', '--quiet',
                                       '--step-deg', '20']) == 0
    data = json.loads(capsys.readouterr().out)
    idf = data['identification']
    assert idf['e_um']['e_ot'] == pytest.approx(10.0, rel=0.05)
    want = {'theta_ot': 90.0, 'theta_p1': 90.0, 'theta_p2': 180.0, 'theta_g': -135.0}
    for key, deg in want.items():
        assert abs((idf['phases_deg'][key] - deg + 180) % 360 - 180) < 3.0, key
    assert idf['output_revolutions'] == pytest.approx(1.0, abs=0.01)
    re = data['reassembly']
    assert re['objective_after_arcmin'] < 0.6 * re['objective_before_arcmin']
    assert data['advice']['method'] == 'identified-assembly-phases'


def test_identify_text(session: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _run(identify, 'identify', [str(session), '--no-recommend']) == 0
    out = capsys.readouterr().out
    assert 'E  = e_ot' in out
    assert 'Q1 = e_p1 + e_g' in out
    assert 'Recommended re-assembly' not in out   # no re-assembly table


def test_identify_bag_without_encoder_data(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    bag = _write_bag(tmp_path / 'info_only', np.zeros(0), np.zeros(0), encoders=False)
    assert _run(identify, 'identify', [str(bag), '--quiet']) == 1
    _one_error_line(capsys, 'EncoderBlock')


def test_identify_empty_encoder_topic(tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    bag = _write_bag(tmp_path / 'empty', np.zeros(0), np.zeros(0))
    assert _run(identify, 'identify', [str(bag), '--quiet']) == 1
    _one_error_line(capsys, 'the encoder topic holds no messages')


def test_identify_nan_samples(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A non-finite sample is left out with a warning (as analyze treats it), not fatal."""
    th = np.linspace(0.0, RATIO * 2 * math.pi, 2000)
    out = th / RATIO
    out[700] = np.nan
    bag = _write_bag(tmp_path / 'nan', th, out)
    assert _run(identify, 'identify', [str(bag), '--quiet', '--no-recommend']) == 0
    assert '1 non-finite or malformed samples left out' in capsys.readouterr().err


def test_identify_without_bench_info(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    th = np.linspace(0.0, RATIO * 2 * math.pi, 2000)
    bag = _write_bag(tmp_path / 'noinfo', th, th / RATIO, info=False)
    assert _run(identify, 'identify', [str(bag), '--quiet']) == 1
    _one_error_line(capsys, 'BenchInfo')


def test_identify_not_a_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _run(identify, 'identify', [str(tmp_path / 'nothing'), '--quiet']) == 1
    _one_error_line(capsys, 'nothing')


def test_identify_bad_step(session: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _run(identify, 'identify', [str(session), '--step-deg', '0', '--quiet']) == 1
    _one_error_line(capsys, '--step-deg')
