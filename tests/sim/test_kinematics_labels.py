"""Mesh labels name the same output order as the number they label."""

from __future__ import annotations

import re

import pytest

from sim.kinematics import kinematics_2kv, kinematics_rv


@pytest.mark.parametrize('kin', [kinematics_2kv(12, 36, 50, 52), kinematics_rv(22, 60, 39, 40),
                                 kinematics_rv(10, 30, 39, 40)])
def test_label_orders_match_mesh_orders(kin) -> None:
    for order, label in zip(kin.mesh_orders_out, kin.mesh_labels, strict=True):
        stated = float(re.search(r'([\d.]+) f_out', label).group(1))
        assert stated == pytest.approx(order, rel=1e-9), label


def test_wang2020_mesh_orders_by_hand() -> None:
    # stage 1: 36 teeth x 26 crank revs relative to the carrier per output rev = 936;
    # stage 2: 52 teeth x 25 absolute crank revs per output rev = 1300 (52 f_w)
    kin = kinematics_2kv(12, 36, 50, 52)
    assert kin.mesh_orders_out == pytest.approx((936.0, 1300.0))
