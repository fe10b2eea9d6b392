"""``rv-te analyze``: the lost motion, backlash and rigidity of a hysteresis record, as JSON
(SI keys) and as lines of the text report (arcmin at the edge)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, TextIO

from rv_te_bench.errors import BagError
from sim.units import rad_to_arcmin

__all__ = ['hysteresis_json', 'print_hysteresis']

_NONE = ('no stretch with the input locked and the output loaded both ways (a hysteresis '
         'test holds the input and loads the output to +T_R and -T_R)')


def _fin(x: float) -> float | None:
    return float(x) if isinstance(x, int | float) and math.isfinite(x) else None


def hysteresis_json(bag: Path, *, rated_torque_nm: float | None,
                    required: bool) -> dict[str, Any] | None:
    """The record's hysteresis (SI), ``{'error': ...}`` when asked for and not readable, or
    None (nothing of the kind in the record, not asked for)."""
    from rv_te_bench.acceptance.record_hysteresis import record_hysteresis
    from rv_te_bench.io.measured_record import read_measured_record

    try:
        record = read_measured_record(bag)
    except BagError as exc:
        return {'error': str(exc)} if required else None
    if record.torque_out_nm is None:
        return {'error': f'{bag}: no torque channel in the record'} if required else None
    h = record_hysteresis(record, rated_torque_nm=rated_torque_nm)
    if h is None:
        return {'error': _NONE} if required else None
    d = h['details']
    return {
        'rated_torque_nm': h['rated_torque_nm'], 'rated_from': h['rated_from'],
        'method': h['method'], 'lost_motion_torque_nm': h['lost_motion_torque_nm'],
        'torque_noise_nm': h['torque_noise_nm'], 'positions': h['positions'],
        'cycles': h['cycles'],
        'stretches_s': [[p.get('found_t_start_s'), p.get('found_t_end_s')]
                        for p in d.get('positions', [])],
        'metrics': {k: _fin(v) for k, v in h['metrics'].items()},
        'spread': {k: _fin(v) for k, v in h['spread'].items()},
        'note': h['note'],
    }


def _arcmin(x: float | None) -> str:
    return f'{float(rad_to_arcmin(x)):.4f} arcmin' if x is not None else '-'


def print_hysteresis(h: dict[str, Any], out: TextIO) -> None:
    """The hysteresis lines of one bag's text report."""
    if 'error' in h:
        print(f'  hysteresis: none ({h["error"]})', file=out)
        return
    per_arcmin = float(rad_to_arcmin(1.0))
    cycles = ', '.join(str(c) for c in h['cycles'])
    method = 'torque steps' if h['method'] == 'torque_steps' else 'constant speed'
    print(f'  hysteresis: input locked, {h["positions"]} stretch(es), {cycles} cycle(s); '
          f'{method}; T_R = {h["rated_torque_nm"]:.5g} N m ({h["rated_from"]}); '
          f'torque noise {h["torque_noise_nm"]:.3g} N m', file=out)
    m, sd = h['metrics'], h['spread']

    def spread(name: str, scale: float = 1.0, unit: str = 'arcmin') -> str:
        v = sd.get(name)
        return f'  (sd over the cycles {v * scale:.2g} {unit})' if v is not None else ''

    print(f'    lost motion (+-{h["lost_motion_torque_nm"]:.4g} N m)  '
          f'{_arcmin(m.get("lost_motion_rad"))}{spread("lost_motion_rad", per_arcmin)}',
          file=out)
    print(f'    backlash (at 0 N m)  {_arcmin(m.get("backlash_rad"))}'
          f'{spread("backlash_rad", per_arcmin)}', file=out)
    for name, v in m.items():
        if name.startswith('torsional_rigidity_'):
            region = name[len('torsional_rigidity_'):-len('_nm_per_rad')]
            val = f'{v / per_arcmin:.2f} N m/arcmin' if v is not None else '-'
            print(f'    torsional rigidity {region}  {val}'
                  f'{spread(name, 1 / per_arcmin, "N m/arcmin")}', file=out)
    loss = m.get('hysteresis_loss_j')
    print(f'    hysteresis loss (loop area)  {loss:.4g} J' if loss is not None
          else '    hysteresis loss (loop area)  -', file=out)
    if h['note']:
        print(f'    not read: {h["note"]}', file=out)
