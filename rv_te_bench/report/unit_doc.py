"""What makes the unit report a document a lab signs: one angle unit, the software that made
it, a report number, the bench's calibration references and the sign-off block.

- **One angle unit** for the whole report (tables, figures, advice): the unit the
  tolerance profile states its TE limit in (``te_pp_arcsec`` -> arcsec, else the unit of
  its first angle limit, else arcmin); rigidity follows it (N m/arcsec or N m/arcmin).
- **Software**: rv-te-bench's version and the git commit of the code that ran (``+dirty``
  when the checkout had changes; "unknown" when the package is not a git checkout and pip
  recorded no commit).
- **Report number** ``RVTE-<date>-<serial>-<8 hex>``: the hash of the record (unit, bench,
  plan, limits, conditions, verdicts and the software), so that two tests, or the same test
  judged by other software, never share a number, and the same record always gets the same.
"""

from __future__ import annotations

import hashlib
import json
import re
import subprocess
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from sim.units import ARCMIN_PER_RAD, ARCSEC_PER_RAD

__all__ = ['PRINT_CSS', 'AngleUnit', 'angle_unit', 'calibration_references', 'calibrations_of',
           'report_number',
           'sign_off_html', 'software_identity']


@dataclass(frozen=True)
class AngleUnit:
    """The report's angle unit: its name, per radian, and why it was chosen."""

    name: str
    per_rad: float
    why: str


ARCMIN = AngleUnit('arcmin', ARCMIN_PER_RAD, 'the default (no angle limit in the profile)')


def angle_unit(report: dict[str, Any]) -> AngleUnit:
    """The one angle unit of this report (module docstring)."""
    keys = [lim['key'] for lim in (report.get('tolerance') or {}).get('limits', [])]
    angular = [k for k in keys if k.endswith(('_arcmin', '_arcsec'))
               and not k.startswith('torsional_rigidity')]
    if not angular:
        return ARCMIN
    key = next((k for k in angular if k.startswith('te_pp_')), angular[0])
    name = key.rsplit('_', 1)[1]
    return AngleUnit(name, ARCSEC_PER_RAD if name == 'arcsec' else ARCMIN_PER_RAD,
                     f'the unit of the tolerance profile\'s limit {key}')


@lru_cache(maxsize=1)
def software_identity() -> dict[str, str]:
    """{'name', 'version', 'commit'} of the code that makes the report."""
    from rv_te_bench import __version__

    return {'name': 'rv-te-bench', 'version': __version__, 'commit': _commit()}


def _commit() -> str:
    here = Path(__file__).resolve().parent
    try:
        head = subprocess.run(['git', '-C', str(here), 'rev-parse', '--short=12', 'HEAD'],
                              capture_output=True, text=True, timeout=10, check=False)
        if head.returncode == 0 and head.stdout.strip():
            dirty = subprocess.run(['git', '-C', str(here), 'status', '--porcelain',
                                    '--untracked-files=no'],
                                   capture_output=True, text=True, timeout=10, check=False)
            return head.stdout.strip() + ('+dirty' if dirty.stdout.strip() else '')
    except (OSError, subprocess.SubprocessError):
        pass
    try:   # installed by pip from a repository: the commit pip recorded
        from importlib.metadata import distribution

        text = distribution('rv-te-bench').read_text('direct_url.json') or '{}'
        commit = json.loads(text).get('vcs_info', {}).get('commit_id', '')
        if commit:
            return str(commit)[:12]
    except (ImportError, OSError, ValueError):
        pass
    return 'unknown (not a git checkout)'


def report_number(report: dict[str, Any], software: dict[str, str]) -> str:
    """``RVTE-<YYYYMMDD>-<serial>-<8 hex>`` (module docstring)."""
    u = report['unit']
    keyed = {k: report.get(k) for k in ('unit', 'bench', 'plan', 'tolerance', 'conditions',
                                        'metrics', 'verdict')}
    keyed['software'] = software
    digest = hashlib.sha256(json.dumps(keyed, sort_keys=True, default=str).encode()).hexdigest()
    day = re.sub(r'\D', '', str(u.get('date_utc', '')))[:8] or '00000000'
    serial = re.sub(r'[^A-Za-z0-9]+', '-', str(u.get('serial', ''))).strip('-')[:24] or 'NA'
    return f'RVTE-{day}-{serial}-{digest[:8].upper()}'


def calibrations_of(report: dict[str, Any]) -> dict[str, str]:
    """The calibration references the record holds, by where they come from: the test's
    conditions (``--condition encoder_out_calibration=CERT-123``), the bag's metadata (a
    bench description's ``metadata: {bench_calibration: ...}``), the scales' serials."""
    b, cond = report['bench'], report.get('conditions') or {}
    out = {str(k): str(v) for k, v in cond.items() if 'calibrat' in str(k).lower()}
    if b.get('bag'):
        from rv_te_bench.errors import BagError
        from rv_te_bench.io.bag_reader import open_bag

        try:
            custom = open_bag(b['bag']).info.get('custom_data') or {}
        except (BagError, OSError):
            custom = {}
        if isinstance(custom, dict):
            out.update({str(k): str(v) for k, v in custom.items()
                        if 'calibrat' in str(k).lower() and str(k) not in out})
    out.update({f'{side} scale serial': b[k] for side, k in (
        ('input', 'encoder_in_scale_serial'), ('output', 'encoder_out_scale_serial'))
        if b.get(k)})
    return out


def calibration_references(calibrations: dict[str, str]) -> str:
    """The references as one line, or what is missing and how to give it."""
    if calibrations:
        return '; '.join(f'{k}: {v}' for k, v in calibrations.items())
    return ('NOT STATED: give them in the bench description (metadata: {bench_calibration: '
            '..., encoder_out_calibration: ...}) or as --condition encoder_out_calibration=...')


def sign_off_html(operator: str) -> str:
    """The sign-off block: tested by / approved by, with lines to sign on paper."""
    def row(role: str, name: str) -> str:
        return (f'<tr><th class="l">{role}</th><td class="l sign">{name}</td>'
                '<td class="sign"></td><td class="sign"></td></tr>')
    from html import escape

    return ('<h2 id="sign-off">Sign-off</h2><table class="signoff"><tr><th class="l"></th>'
            '<th class="l">name</th><th>signature</th><th>date</th></tr>'
            + row('tested by', escape(operator)) + row('approved by', '')
            + '</table><p class="muted">The results relate only to the unit tested, under the '
            'conditions stated. This report shall not be reproduced except in full.</p>')


#: Screen and print (Chromium's "print to PDF"): A4, the verdict table and each figure kept
#: on one page, the identity block repeated nowhere but at the top.
PRINT_CSS = """
.signoff td.sign{min-width:12em;height:2.6em;border-bottom:1px solid #222}
.ident td,.ident th,.signoff th{text-align:left}.dir{white-space:nowrap}
@page{size:A4;margin:12mm}
@media print{body{max-width:none;margin:0;font-size:9.5pt}
section.keep,table.verdict,table.signoff,.ident,figure,img{break-inside:avoid;
page-break-inside:avoid}
h2{break-after:avoid;page-break-after:avoid}
.badge{-webkit-print-color-adjust:exact;print-color-adjust:exact}}
"""
