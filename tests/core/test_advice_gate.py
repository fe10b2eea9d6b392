"""core.advice_gate: the one gate of rv-te analyze and the compensation node (issue 33 s.4).

Expected decisions from what the compensations act on (Hu 2020 Eq. 27: the tooth profile, the
cycloid-pin mesh lines; Wang 2020: the eccentricity lines), on the Wang 2020 2K-V orders
(i = 79, f_w = 25 f_out, mesh orders 936 / 1300; DESIGN.md s.4).
"""

from __future__ import annotations

import math

import pytest

from rv_te_bench.core.advice_gate import (
    check_cause,
    dominant_line,
    is_mesh_line,
    likely_source,
    withheld_without_revolution,
)
from rv_te_bench.core.orders import OrderSet
from sim.units import arcmin_to_rad

ORDERS = OrderSet(gear_ratio=79.0, crank_per_output=25.0, n_crank_harmonics=3,
                  mesh_orders_out=(936.0, 1300.0), mesh_labels=('36 f_w_rel', '52 f_w'))


def test_no_whole_revolution_withholds_naming_what_the_record_covers() -> None:
    reason = withheld_without_revolution(0.25, whole_revolution=False)
    assert reason is not None and reason.startswith('advice withheld')
    assert '0.25 output revolutions' in reason
    assert 'its samples' in (withheld_without_revolution(math.nan, False) or '')
    assert withheld_without_revolution(0.25, whole_revolution=True) is None


@pytest.mark.parametrize(('order', 'mesh'), [(936.0, True), (1300.0, True), (25.0, False),
                                             (1.0, False), (936.5, False)])
def test_mesh_lines(order: float, mesh: bool) -> None:
    assert is_mesh_line(order, ORDERS) is mesh


def test_tooth_profile_against_the_crank_line_is_withheld_naming_both() -> None:
    src = likely_source(25.0, ORDERS, 'rv')
    assert 'crankshaft' in src
    gate = check_cause('tooth-profile', label='1 f_w', amplitude_rad=float(arcmin_to_rad(0.6)),
                       source=src, mesh=False)
    assert gate.withheld is not None and gate.note == ''
    assert '1 f_w (0.6 arcmin)' in gate.withheld and src in gate.withheld


def test_tooth_profile_against_a_mesh_line_stands() -> None:
    gate = check_cause('tooth-profile', label='mesh', amplitude_rad=1e-4,
                       source=likely_source(936.0, ORDERS, 'rv'), mesh=True)
    assert gate.withheld is None and gate.note == ''


@pytest.mark.parametrize('method', ['assembly-phases', 'identified-assembly-phases'])
def test_assembly_phases_against_a_mesh_line_carry_a_note(method: str) -> None:
    gate = check_cause(method, label='mesh 52 f_w', amplitude_rad=float(arcmin_to_rad(0.5)),
                       source=likely_source(1300.0, ORDERS, '2kv'), mesh=True)
    assert gate.withheld is None
    assert 'mesh line' in gate.note and 'eccentricity lines' in gate.note
    assert check_cause(method, label='1 f_w', amplitude_rad=1e-4, source='crank',
                       mesh=False).note == ''


def test_dominant_line_skips_non_finite() -> None:
    assert dominant_line([1.0, 25.0, 936.0], [1e-5, 3e-4, math.nan]) == 1
    assert dominant_line([], []) is None
