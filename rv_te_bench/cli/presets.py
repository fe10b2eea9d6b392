"""``rv-te presets [NAME] [--set key=value ...] [--json]``: list presets or show one."""

from __future__ import annotations

import argparse
import json
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers


def register(subparsers: Subparsers) -> None:
    """Add the ``presets`` subcommand."""
    p = subparsers.add_parser(
        'presets', help='list reducer presets, or show every value of one with unit and source',
        description='List the shipped reducer presets, or show one preset (after overrides).',
        epilog='examples:\n  rv-te presets\n  rv-te presets wang2020-2kv --json\n'
               '  rv-te presets wang2020-2kv --set mesh.stiffness_n_m=9e7',
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('name', nargs='?', help='preset name or path to a preset TOML file')
    p.add_argument('--set', dest='overrides', action='append', default=[], metavar='KEY=VALUE',
                   help='override a preset value (repeatable)')
    p.add_argument('--json', action='store_true', help='machine-readable output')
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """List presets or describe one; 0 on success (errors raise PresetError)."""
    from sim.presets import available_presets, load_preset

    if not args.name:
        rows = []
        for name in available_presets():
            preset = load_preset(name)
            rows.append({'name': name, 'model': preset.model,
                         'description': preset.description})
        if args.json:
            print(json.dumps({'presets': rows}, indent=2))
        else:
            for r in rows:
                print(f"{r['name']:<22} {r['model']:<14} {r['description']}")
        return 0
    preset = load_preset(args.name, args.overrides)
    rows = preset.describe_rows()
    if args.json:
        print(json.dumps({'name': preset.name, 'model': preset.model,
                          'description': preset.description, 'values': rows}, indent=2,
                         default=str))
        return 0
    print(f'{preset.name} ({preset.model}): {preset.description}')
    width = max(len(r['key']) for r in rows) if rows else 10
    for r in rows:
        note = f"  [{r['note']}]" if r['note'] else ''
        print(f"  {r['key']:<{width}}  {r['value']!s:>14} {r['unit']:<8} {r['source']}{note}")
    return 0
