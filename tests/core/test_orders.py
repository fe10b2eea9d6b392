"""core.orders.OrderSet: which lines are reported, their labels, the validation."""

from __future__ import annotations

import math

import pytest

from rv_te_bench.core.orders import OrderSet
from rv_te_bench.errors import TeConfigError
from sim.bench_info import BenchInfoData


def test_wang2020_lines_in_order_with_labels() -> None:
    s = OrderSet(79.0, 25.0, mesh_orders_out=(1300.0,), mesh_labels=('52 f_w',),
                 n_crank_harmonics=3)
    assert s.lines() == [(1.0, 'f_out'), (25.0, '1 f_w'), (50.0, '2 f_w'), (75.0, '3 f_w'),
                         (24.0, 'f_w - f_out'), (26.0, 'f_w + f_out'), (1300.0, '52 f_w')]
    assert s.crank_order(50.0) == 2.0


def test_duplicates_keep_the_first_label_and_unlabelled_meshes_are_numbered() -> None:
    # crank order 1: f_w coincides with f_out, the lower sideband is at order 0 (left out)
    s = OrderSet(10.0, 1.0, mesh_orders_out=(2.0, 7.0), n_crank_harmonics=1)
    assert s.lines() == [(1.0, 'f_out'), (2.0, 'f_w + f_out'), (7.0, 'mesh 2')]


def test_from_bench_info_takes_the_absolute_crank_rate() -> None:
    info = BenchInfoData(gear_ratio=79.0, crank_per_input=-25.0 / 79.0, mesh_orders=(1300.0,),
                         mesh_labels=('mesh',))
    s = OrderSet.from_bench_info(info)
    assert s.crank_per_output == pytest.approx(25.0)
    assert s.mesh_orders_out == (1300.0,)
    assert s.mesh_labels == ('mesh',)


def test_from_bench_info_with_the_command_line_over_the_record() -> None:
    """--ratio replaces the ratio but the crank order stays the record's (|-25/79| x 79);
    --crank-per-output replaces the crank order; a bad record ratio is named."""
    info = BenchInfoData(gear_ratio=79.0, crank_per_input=-25.0 / 79.0)
    s = OrderSet.from_bench_info(info, 3, gear_ratio=80.0)
    assert (s.gear_ratio, s.crank_per_output, s.n_crank_harmonics) == (80.0, pytest.approx(25.0), 3)
    s = OrderSet.from_bench_info(info, crank_per_output=30.0)
    assert (s.gear_ratio, s.crank_per_output) == (79.0, 30.0)
    with pytest.raises(TeConfigError, match=r'gear_ratio must be finite and > 0, got 0\.0'):
        OrderSet.from_bench_info(BenchInfoData(gear_ratio=0.0, crank_per_input=-0.3))


@pytest.mark.parametrize(('sign', 'expected'), [(-1.0, -25.0 / 79.0), (1.0, 25.0 / 79.0)])
def test_crank_per_input_is_the_wire_form_of_the_crank_order(sign: float,
                                                              expected: float) -> None:
    orders = OrderSet(gear_ratio=79.0, crank_per_output=25.0)
    assert orders.crank_per_input(sign) == pytest.approx(expected, rel=1e-15)
    back = OrderSet.from_bench_info(BenchInfoData(gear_ratio=79.0,
                                                  crank_per_input=orders.crank_per_input(sign)))
    assert back.crank_per_output == pytest.approx(25.0, rel=1e-15)


@pytest.mark.parametrize(('kwargs', 'needle'), [
    ({'gear_ratio': 0.0}, 'gear_ratio must be finite and > 0, got 0.0'),
    ({'gear_ratio': math.nan}, 'gear_ratio must be finite and > 0, got nan'),
    ({'crank_per_output': -1.0}, 'crank_per_output must be finite and > 0, got -1.0'),
    ({'mesh_orders_out': (5.0, math.inf)}, 'mesh_orders_out[1] must be finite and > 0'),
    ({'mesh_orders_out': (5.0,), 'mesh_labels': ('a', 'b')}, '2 labels for 1 orders'),
    ({'n_crank_harmonics': True}, 'n_crank_harmonics must be an int in 0..200, got True'),
    ({'n_crank_harmonics': -1}, 'n_crank_harmonics must be an int in 0..200, got -1'),
])
def test_bad_values_are_named(kwargs: dict[str, object], needle: str) -> None:
    args: dict[str, object] = {'gear_ratio': 79.0, 'crank_per_output': 25.0, **kwargs}
    with pytest.raises(TeConfigError) as err:
        OrderSet(**args)  # type: ignore[arg-type]
    assert needle in str(err.value)
