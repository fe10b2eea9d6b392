"""BenchInfo.parameters_yaml records the overrides so consumers rebuild the same preset."""

from __future__ import annotations

from rv_te_bench.io.bench_record import overrides_from_parameters_yaml
from sim.bench import BenchConfig, BenchSimulator
from sim.drive import ConstantSpeed
from sim.presets import load_preset


def test_overrides_round_trip_through_bench_info() -> None:
    ov = ('eccentricity.e_p1_m=1.5e-05',)
    sim = BenchSimulator(BenchConfig(preset='wang2020-2kv', drive=ConstantSpeed(300.0),
                                     overrides=ov, encoder_in='ideal', encoder_out='ideal'))
    got = overrides_from_parameters_yaml(sim.info.parameters_yaml)
    assert got == list(ov)
    assert load_preset('wang2020-2kv', got)['eccentricity.e_p1_m'] == 1.5e-05


def test_unreadable_record_gives_no_overrides() -> None:
    assert overrides_from_parameters_yaml('') == []
    assert overrides_from_parameters_yaml('[unclosed') == []
    assert overrides_from_parameters_yaml('bench: 3') == []
