"""A unit report of a short plan of every kind run on the simulated bench (li2023-rv), shared
by the unit report's tests (screen, print to PDF, figures, units)."""

from __future__ import annotations

import copy
import re
from typing import Any

import numpy as np

from tests.acceptance.recorded_data import QUICK, run_plan

#: The same limits as the shipped li2023-rv profile, stated in arcsec (1 arcmin = 60 arcsec).
ARCSEC_LIMITS = {'profile': 'lab-arcsec', 'limits': {
    'te_pp_arcsec': {'max': 60.0, 'source': 'lab procedure QP-7'},
    'lost_motion_arcsec': {'max': 60.0, 'source': 'lab procedure QP-7'},
    'backlash_arcsec': {'max': 60.0, 'source': 'lab procedure QP-7'},
    'torsional_rigidity_nm_per_arcmin': {'min': 108, 'region': 'K',
                                         'source': 'lab procedure QP-7'}}}
ARCMIN_PER_RAD = 60 * 180 / np.pi          # the constants, not the package's
ARCSEC_PER_RAD = 3600 * 180 / np.pi


def quick_report(serial: str = 'RV-4711', operator: str = 'A. Tester',
                 limits: dict[str, Any] | None = None) -> dict[str, Any]:
    """The report of the QUICK plan (TE both directions, hysteresis, sweep)."""
    rep = copy.deepcopy(run_plan(QUICK, limits=limits).report)
    rep['unit'].update(serial=serial, operator=operator)
    return rep


def same_te_both_directions(report: dict[str, Any]) -> dict[str, Any]:
    """The report with the cw curve made equal to the ccw one (the case where an overlaid
    cw curve hides the ccw curve completely)."""
    rep = copy.deepcopy(report)
    rows = rep['steps'][0]['rows']
    ccw = next(r for r in rows if r['direction'] == 'ccw')
    for r in rows:
        if r['direction'] == 'cw':
            r['position_rad'] = list(ccw['position_rad'])
            r['te_by_position_rad'] = list(ccw['te_by_position_rad'])
    return rep


def visible_text(html: str) -> str:
    """The page's text without tags, styles and embedded images."""
    html = re.sub(r'<style>.*?</style>', ' ', html, flags=re.S)
    return re.sub(r'<[^>]+>', ' ', html)
