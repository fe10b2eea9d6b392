"""``rv-te analyze``: table, JSON, report files, comparison, bad input and exit codes.

Expected numbers come from the TE written into the synthetic bags (see
``tests/report/synthetic_bags.py``): 1 f_w = 0.6', 2 f_w = 0.2', f_out = 0.1', mean -0.15'.
"""

from __future__ import annotations

import argparse
import base64
import json
import re
from typing import TYPE_CHECKING

import numpy as np
import pytest

from rv_te_bench.cli import analyze
from sim.units import arcmin_to_rad, rad_to_arcmin
from tests.report.synthetic_bags import CRANK_PER_OUTPUT, RATIO, Harmonic, write_bag

if TYPE_CHECKING:
    from pathlib import Path

MEAN = float(arcmin_to_rad(-0.15))
HARMONICS = (
    Harmonic(25.0, float(arcmin_to_rad(0.6)), 0.3),
    Harmonic(50.0, float(arcmin_to_rad(0.2)), -1.0),
    Harmonic(1.0, float(arcmin_to_rad(0.1)), 0.5),
)
HALF = tuple(Harmonic(h.output_order, 0.5 * h.amplitude_rad, h.phase_rad) for h in HARMONICS)
PNG_MAGIC = b'\x89PNG\r\n\x1a\n'


def parse(argv: list[str]) -> argparse.Namespace:
    """Parse like ``rv-te analyze`` does (tests call ``run`` directly)."""
    parser = argparse.ArgumentParser(prog='rv-te analyze')
    analyze.add_arguments(parser)
    return parser.parse_args(argv)


def call(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    rc = analyze.run(parse([*argv, '--quiet']))
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture(scope='module')
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, object]]:
    root = tmp_path_factory.mktemp('cli')
    before = root / 'before'
    after = root / 'after'
    return {'before': (before, write_bag(before, harmonics=HARMONICS, mean_rad=MEAN,
                                         duration_s=4.5)),
            'after': (after, write_bag(after, harmonics=HALF, mean_rad=0.5 * MEAN,
                                       duration_s=4.5))}


def test_table_on_stdout(bags: dict, capsys: pytest.CaptureFixture[str]) -> None:
    path, synth = bags['before']
    rc, out, err = call([str(path)], capsys)
    assert rc == 0, err
    te = synth.te_rad
    pp = float(rad_to_arcmin(te.max() - te.min()))
    m = re.search(r'cumulative\s+(-?\d+\.\d+)\s+(-?\d+\.\d+)\s+(-?\d+\.\d+)', out)
    assert m is not None, out
    assert float(m.group(1)) == pytest.approx(pp, abs=1e-4)           # printed to 4 decimals
    assert float(m.group(2)) == pytest.approx(float(rad_to_arcmin(np.abs(te).max())), abs=1e-4)
    # amplitude, its U, phase (0.3 rad = 17.2 deg), its U
    assert re.search(r'1 f_w\s+25\s+1\s+12\.5\s+0\.6000\s+\S+\s+17\.2\s+\S+', out), out
    assert 'dominant: 1 f_w' in out
    assert 'gaps: none' in out
    assert 'ERROR' not in err


def test_json_has_unit_keys_and_values(bags: dict, capsys: pytest.CaptureFixture[str]) -> None:
    path, synth = bags['before']
    rc, out, _ = call([str(path), '--json'], capsys)
    assert rc == 0
    doc = json.loads(out)
    bag = doc['bags'][0]
    assert doc['comparison'] is None
    cum = bag['cumulative']
    te = synth.te_rad
    assert cum['te_pp_arcmin'] == pytest.approx(float(rad_to_arcmin(te.max() - te.min())),
                                                rel=1e-9)
    assert cum['te_mean_arcmin'] == pytest.approx(float(rad_to_arcmin(te.mean())), rel=1e-9)
    assert {'te_amplitude_arcmin', 'te_std_arcmin', 'n_samples'} <= cum.keys()
    lines = {ln['label']: ln for ln in bag['spectrum']['lines']}
    assert lines['1 f_w']['amplitude_arcmin'] == pytest.approx(0.6, rel=1e-6)
    assert lines['1 f_w']['output_order'] == 25.0
    assert lines['1 f_w']['frequency_hz'] == pytest.approx(12.5, rel=1e-3)
    assert lines['2 f_w']['phase_rad'] == pytest.approx(-1.0, abs=1e-6)
    assert bag['dominant']['label'] == '1 f_w'
    assert bag['windows'][0]['complete'] is True
    assert bag['bench']['gear_ratio'] == RATIO
    assert bag['partial'] is False


def test_report_files_and_overwrite_rule(bags: dict, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    path, _ = bags['before']
    rep = tmp_path / 'rep'
    rc, _, err = call([str(path), '--report', str(rep)], capsys)
    assert rc == 0, err
    for name in ('te.png', 'spectrum.png', 'report.html', 'report.json'):
        assert (rep / name).is_file(), name
    assert (rep / 'te.png').read_bytes().startswith(PNG_MAGIC)
    page = (rep / 'report.html').read_text(encoding='utf-8')
    blobs = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    assert len(blobs) == 2
    assert {base64.b64decode(b) for b in blobs} == {(rep / 'te.png').read_bytes(),
                                                    (rep / 'spectrum.png').read_bytes()}
    assert 'src="te.png"' not in page  # self-contained
    assert 'Dominant harmonic' in page and 'Recommendation' in page
    doc = json.loads((rep / 'report.json').read_text(encoding='utf-8'))
    assert doc['bags'][0]['cumulative']['te_pp_arcmin'] > 0
    before = (rep / 'report.json').stat().st_mtime_ns

    rc, _, err = call([str(path), '--report', str(rep)], capsys)
    assert rc == 1
    assert err.strip().splitlines()[-1].startswith('ERROR: ')
    assert 'exists already' in err and '--force' in err
    assert (rep / 'report.json').stat().st_mtime_ns == before

    rc, _, _ = call([str(path), '--report', str(rep), '--force'], capsys)
    assert rc == 0


def test_comparison_of_two_bags(bags: dict, tmp_path: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    (p_before, _), (p_after, _) = bags['before'], bags['after']
    rep = tmp_path / 'cmp'
    rc, out, _ = call([str(p_before), str(p_after), '--json', '--report', str(rep)], capsys)
    assert rc == 0
    rows = json.loads(out)['comparison']
    assert [r['bag'] for r in rows] == [str(p_before), str(p_after)]
    # every TE component and the mean halved: p-p and amplitude halve exactly
    assert rows[0]['te_pp_change_pct'] == pytest.approx(0.0, abs=1e-12)
    assert rows[1]['te_pp_change_pct'] == pytest.approx(-50.0, abs=1e-9)
    assert rows[1]['te_amplitude_change_pct'] == pytest.approx(-50.0, abs=1e-9)
    assert rows[1]['dominant_amplitude_arcmin'] == pytest.approx(0.3, rel=1e-6)
    assert (rep / 'comparison.png').read_bytes().startswith(PNG_MAGIC)
    assert 'Comparison (first bag = reference)' in (rep / 'report.html').read_text('utf-8')

    rc, out, _ = call([str(p_before), str(p_after)], capsys)
    assert rc == 0
    assert re.search(r'after\s+\S+\s+\S+\s+\S+\s+\S+\s+1 f_w\s+-50\.0\s+-50\.0', out), out


def test_progress_lines_on_stderr(bags: dict, capsys: pytest.CaptureFixture[str],
                                  monkeypatch: pytest.MonkeyPatch) -> None:
    path, _ = bags['before']
    monkeypatch.setattr(analyze, 'PROGRESS_PERIOD_S', 0.0)
    rc = analyze.run(parse([str(path)]))
    out, err = capsys.readouterr()
    assert rc == 0
    assert re.search(r'\d+ blocks, \d+\.\d+ M samples, \d+ blocks/s', err)
    assert 'blocks/s' not in out


def test_bag_without_bench_info(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / 'real'
    write_bag(path, harmonics=HARMONICS, duration_s=2.5, with_info=False)
    rc, out, err = call([str(path)], capsys)
    assert rc == 1
    assert out == ''
    assert err.count('ERROR: ') == 1
    assert '--ratio and --crank-per-output' in err
    rc, out, _ = call([str(path), '--ratio', str(RATIO), '--crank-per-output',
                       str(CRANK_PER_OUTPUT)], capsys)
    assert rc == 0
    assert 'ratio from cli' in out


def _mcap(path: Path) -> Path:
    (file,) = sorted(path.glob('*.mcap'))
    return file


def test_truncated_bag_gives_partial_result(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / 'cut'
    write_bag(path, harmonics=HARMONICS, mean_rad=MEAN, duration_s=6.5)
    file = _mcap(path)
    data = file.read_bytes()
    file.write_bytes(data[: int(len(data) * 0.6)])
    rc, out, err = call([str(path), '--json'], capsys)
    assert rc == 0
    bag = json.loads(out)['bags'][0]
    assert bag['partial'] is True
    assert bag['problems'] and 'part of the bag is unreadable' in bag['problems'][0]
    assert 0 < bag['blocks_read'] < 65
    assert 'PARTIAL' in err
    # 60 % of the file holds more than one whole revolution: what was read is sound
    assert bag['spectrum']['n_windows'] >= 1
    lines = {ln['label']: ln for ln in bag['spectrum']['lines']}
    assert lines['1 f_w']['amplitude_arcmin'] == pytest.approx(0.6, rel=1e-6)
    assert lines['1 f_w']['phase_rad'] == pytest.approx(0.3, abs=1e-6)


@pytest.mark.parametrize('keep_bytes', [0, 40])
def test_unreadable_bag_fails(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                              keep_bytes: int) -> None:
    path = tmp_path / 'broken'
    write_bag(path, harmonics=HARMONICS, duration_s=2.5)
    file = _mcap(path)
    file.write_bytes(file.read_bytes()[:keep_bytes])
    rc, out, err = call([str(path)], capsys)
    assert rc == 1
    assert out == ''
    assert err.startswith('ERROR: ') and str(path) in err


def test_no_encoder_topic_and_wrong_type(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / 'info_only'
    write_bag(path, harmonics=HARMONICS, with_blocks=False)
    rc, _, err = call([str(path)], capsys)
    assert rc == 1
    assert 'ERROR: ' in err and 'EncoderBlock' in err
    path2 = tmp_path / 'ok'
    write_bag(path2, harmonics=HARMONICS, duration_s=1.0)
    rc, _, err = call([str(path2), '--topic', '/bench/info'], capsys)
    assert rc == 1
    assert "has type 'rv_te_msgs/msg/BenchInfo'" in err
    rc, _, err = call([str(path2), '--topic', '/nope'], capsys)
    assert rc == 1
    assert "no topic '/nope'" in err
    rc, _, err = call([str(tmp_path / 'missing')], capsys)
    assert rc == 1
    assert 'no such bag' in err


@pytest.mark.parametrize('argv', [
    [],
    ['bag', '--ratio', '-3'],
    ['bag', '--crank-per-output', 'nan'],
    ['bag', '--window-revolutions', '0'],
    ['bag', '--harmonics', 'x'],
])
def test_bad_usage_exits_2(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        parse(argv)
    assert exc.value.code == 2
    assert 'usage:' in capsys.readouterr().err


def test_register_sets_run() -> None:
    parser = argparse.ArgumentParser(prog='rv-te')
    sub = parser.add_subparsers(dest='command')
    analyze.register(sub)
    args = parser.parse_args(['analyze', 'some.mcap', '--json'])
    assert args.func is analyze.run
    assert args.json is True


def test_not_a_bag_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / 'notes.mcap'
    path.write_text('these are not the bytes you are looking for\n', encoding='utf-8')
    rc, out, err = call([str(path)], capsys)
    assert rc == 1
    assert out == ''
    assert err.startswith('ERROR: ') and 'notes.mcap' in err


def test_shorter_than_one_revolution(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / 'short'
    synth = write_bag(path, harmonics=HARMONICS, mean_rad=MEAN, duration_s=1.5)  # 0.75 rev
    rep = tmp_path / 'rep'
    rc, out, err = call([str(path), '--json', '--report', str(rep)], capsys)
    assert rc == 0
    bag = json.loads(out)['bags'][0]
    assert bag['spectrum'] is None and bag['dominant'] is None
    assert bag['partial'] is False
    assert 'no complete output revolution' in err
    te = synth.te_rad
    assert bag['cumulative']['te_pp_arcmin'] == pytest.approx(
        float(rad_to_arcmin(te.max() - te.min())), rel=1e-9)
    assert (rep / 'spectrum.png').read_bytes().startswith(PNG_MAGIC)
    assert 'No complete output revolution' in (rep / 'report.html').read_text('utf-8')
