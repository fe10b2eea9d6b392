"""Every preset's stiffness, backlash and lost motion against its cited source (issue 33 s.5).

The shipped plan's hysteresis step (one output position) on each preset's simulated bench;
the expected values are the sources' numbers written here: the Nabtesco RV-E catalogue for
the RV-80E (torsional rigidity 196 N m/arcmin b/a at 50-100 % of 784 N m, lost motion and
backlash 1 arcmin), Wang 2020's mesh stiffness for the 2K-V (2 k r_p^2 with k = 8.43e7 N/m,
r_p = 65 mm cos 20 deg: 183 N m/arcmin with both pairs in contact), the RV-40E class
minimum for Li 2023's unit. Before: the RV-80E presets gave 1968 N m/arcmin (the tooth
contacts alone), ten times the catalogue, so the 196 limit could never fail. Every limit's
source cites a document the user has (before: "DESIGN.md s.6", not in the repository).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
import yaml

from rv_te_bench.acceptance import load_tolerance, parse_plan, run_plan_offline
from sim.program import ProgramSimulator

ARCMIN_PER_RAD = 10800.0 / math.pi
REPO = Path(__file__).resolve().parents[2]
PLANS = REPO / 'rv_te_bench' / 'acceptance' / 'plans'
K_WANG = 2 * 8.43e7 * (0.065 * math.cos(math.radians(20))) ** 2 / ARCMIN_PER_RAD  # 183


def _hysteresis(preset: str, plan: str, mode: str) -> dict[str, float]:
    doc = yaml.safe_load((PLANS / f'{plan}.yaml').read_text(encoding='utf-8'))
    doc['steps'] = [dict(s, positions=1) for s in doc['steps'] if s['kind'] == 'hysteresis']
    profile, _ = load_tolerance(preset)
    sim = ProgramSimulator(preset=preset, te_mode=mode, sample_rate_hz=1000.0, block_size=100,
                           seed=1)
    report = run_plan_offline(parse_plan(doc), profile, serial='CAT-1', operator='t', sim=sim)
    out = {}
    for m in report['metrics']:
        if m.get('value') is None:
            continue
        if m['name'] == 'torsional_rigidity_K_nm_per_rad':
            out['k'] = m['value'] / ARCMIN_PER_RAD
        elif m['name'] in ('lost_motion_rad', 'backlash_rad'):
            out[m['name'].removesuffix('_rad')] = m['value'] * ARCMIN_PER_RAD
    return out


@pytest.mark.parametrize('preset', ['rv-80e-101', 'hu2020-rv', 'hu2020-rv-modified'])
def test_rv80e_presets_meet_the_catalogue_but_not_by_ten_times(preset: str) -> None:
    got = _hysteresis(preset, 'rv-80e', 'geometric')
    # a good unit: at or above the catalogue's 196, within 15 % of it (a limit that can fail)
    assert 196.0 <= got['k'] <= 196.0 * 1.15, got
    assert got['lost_motion'] <= 1.0 and got['backlash'] <= 1.0, got
    assert got['backlash'] <= got['lost_motion'], got


def test_wang_2kv_is_its_mesh_stiffness() -> None:
    got = _hysteresis('wang2020-2kv', 'wang2020-2kv', 'ste')
    assert abs(K_WANG - 183.0) < 1.0
    assert got['k'] == pytest.approx(K_WANG, rel=0.03), got


def test_li2023_meets_its_class_minimum() -> None:
    got = _hysteresis('li2023-rv', 'li2023-rv', 'dte')
    assert got['k'] >= 108.0 and got['lost_motion'] <= 1.0 and got['backlash'] <= 1.0, got


def test_limit_sources_cite_documents_the_user_has() -> None:
    """A source naming a .md file names one in the repository (and no DESIGN.md)."""
    folder = REPO / 'rv_te_bench' / 'acceptance' / 'tolerances'
    for f in sorted(folder.glob('*.yaml')):
        text = f.read_text(encoding='utf-8')
        assert 'DESIGN.md' not in text, f.name
        for cited in re.findall(r'([\w./-]+\.md)\b', text):
            assert (REPO / cited).is_file(), (f.name, cited)
