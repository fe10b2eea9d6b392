"""``rv-te info BAG [--json]``: the first look at a bag, as ``ros2 bag info`` gives it.

Duration, start, storage files, every topic with its type and message count (read from the
file, beside what metadata.yaml claims), the bench (BenchInfo: id, preset, reducer, ratio,
sample rate, encoders), the unit under test (session metadata: serial, operator) and the
gaps of the encoder stream (sequence numbers skipped: blocks lost). Reads the bag, changes
nothing, records nothing.

Exit codes: 0 ok, 1 not a readable bag (one ``ERROR:`` line), 2 bad usage.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers

__all__ = ['bag_info', 'register', 'run']

_GAPS_LISTED = 20


def register(subparsers: Subparsers) -> None:
    """Add the ``info`` subcommand."""
    p = subparsers.add_parser(
        'info', help='first look at a bag: duration, topics, counts, bench, unit, gaps',
        description=__doc__.split('\n\n', 1)[1].rsplit('\n\nExit codes', 1)[0],
        epilog='examples:\n  rv-te info bags/sample\n  rv-te info bags/sample --json',
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('bag', type=Path, help='bag folder (or its .mcap / .db3 file)')
    p.add_argument('--json', action='store_true', help='print one JSON document')
    p.set_defaults(func=run)


def _utc(ns: int | None) -> str:
    if ns is None:
        return ''
    return dt.datetime.fromtimestamp(ns / 1e9, tz=dt.UTC).isoformat(timespec='milliseconds')


def _encoder_gaps(path: Path) -> dict[str, Any]:
    """Blocks, samples and the sequence numbers skipped on the encoder topic."""
    from rv_te_bench.core.stream_records import EncoderBatch
    from rv_te_bench.errors import BagError
    from rv_te_bench.io.bag_reader import read_encoder_batches

    seqs: list[np.ndarray] = []
    samples = 0
    try:
        stream = read_encoder_batches(path, None, strict=False)
        for item in stream:        # batches, and blocks that fit no batch
            if isinstance(item, EncoderBatch):
                seqs.append(np.asarray(item.seq, dtype=np.int64))
                samples += int(item.n_samples)
            else:
                seqs.append(np.array([item.seq], dtype=np.int64))
                samples += int(np.size(item.theta_out_rad))
    except BagError as exc:
        return {'topic_problem': str(exc), 'blocks': 0, 'samples': 0, 'gaps': [],
                'blocks_missing': 0}
    seq = np.concatenate(seqs) if seqs else np.zeros(0, dtype=np.int64)
    jumps = np.flatnonzero(np.diff(seq) != 1)
    gaps = [{'after_seq': int(seq[k]), 'next_seq': int(seq[k + 1]),
             'blocks_missing': int(max(seq[k + 1] - seq[k] - 1, 0))} for k in jumps]
    first = int(seq[0]) if seq.size else 0
    return {'blocks': int(seq.size), 'samples': samples, 'first_seq': first,
            'gaps': gaps, 'blocks_missing': first + sum(g['blocks_missing'] for g in gaps)}


def bag_info(path: Path) -> dict[str, Any]:
    """Everything ``rv-te info`` shows (SI units, JSON-able).

    Raises:
        BagError: Not a readable bag.
    """
    from rv_te_bench.errors import BenchInfoError
    from rv_te_bench.io.bag_reader import bag_summary, read_bench_info
    from rv_te_bench.report.analysis import session_info

    summary = bag_summary(path)
    bench: dict[str, Any] | None
    try:
        info = read_bench_info(path)
        bench = {'bench_id': info.bench_id, 'preset': info.preset,
                 'reducer_type': info.reducer_type, 'gear_ratio': info.gear_ratio,
                 'sample_rate_hz': info.sample_rate_hz, 'block_size': info.block_size,
                 'encoder_in_model': info.encoder_in_model,
                 'encoder_out_model': info.encoder_out_model}
    except BenchInfoError as exc:
        bench = {'problem': str(exc)}
    s = session_info(path)
    return {
        'bag': summary['path'], 'files': summary['files'], 'finalized': summary['finalized'],
        'start_utc': _utc(summary['start_ns']), 'duration_s': summary['duration_s'],
        'message_count': summary['message_count'], 'topics': summary['topics'],
        'bench': bench,
        'unit': {'serial': s.unit_serial, 'operator': s.operator, 'session': s.name,
                 'temperature_c': s.temperature_c, 'imported_from': s.imported_from},
        'encoders': _encoder_gaps(Path(path)),
        'problems': summary['problems'], 'notes': summary['notes'],
    }


def _lines(doc: dict[str, Any]) -> list[str]:
    enc = doc['encoders']
    out = [f"bag:       {doc['bag']}",
           f"files:     {', '.join(Path(f).name for f in doc['files'])}"
           + ('' if doc['finalized'] else '  (not finalised: recorder stopped early?)'),
           f"start:     {doc['start_utc'] or '-'}",
           f"duration:  {doc['duration_s']:.3f} s",
           f"messages:  {doc['message_count']}"]
    b = doc['bench'] or {}
    if 'problem' in b:
        out.append(f"bench:     no readable BenchInfo ({b['problem']})")
    else:
        out.append(f"bench:     {b['bench_id']}  preset {b['preset']} ({b['reducer_type']}), "
                   f"i = {b['gear_ratio']:g}, {b['sample_rate_hz']:g} Hz, "
                   f"encoders {b['encoder_in_model']} / {b['encoder_out_model']}")
    u = doc['unit']
    out.append(f"unit:      serial {u['serial'] or '- (not stated)'}  operator "
               f"{u['operator'] or '-'}  session {u['session']}")
    if 'topic_problem' in enc:
        out.append(f"encoders:  {enc['topic_problem']}")
    else:
        out.append(f"encoders:  {enc['blocks']} blocks, {enc['samples']} samples, "
                   f"{len(enc['gaps'])} gap(s), {enc['blocks_missing']} block(s) missing")
        for g in enc['gaps'][:_GAPS_LISTED]:
            out.append(f"           gap after seq {g['after_seq']}: next {g['next_seq']} "
                       f"({g['blocks_missing']} missing)")
        if len(enc['gaps']) > _GAPS_LISTED:
            out.append(f"           ... {len(enc['gaps']) - _GAPS_LISTED} more (--json)")
    out.append('topics:')
    width = max([len(n) for n in doc['topics']] + [5])
    for name, t in doc['topics'].items():
        claim = t.get('count_metadata_yaml')
        differs = '' if claim is None or claim == t['count'] else \
            f'  (metadata.yaml says {claim})'
        out.append(f"  {name:<{width}}  {t['count']:>8}  {t['type']}{differs}")
    out += [f'problem: {p}' for p in doc['problems']] + [f'note: {n}' for n in doc['notes']]
    return out


def run(args: argparse.Namespace) -> int:
    """Show the bag; 0 on success (a bad bag raises BagError: exit 1, one line)."""
    doc = bag_info(args.bag)
    if args.json:
        print(json.dumps(doc, indent=2, default=str))
    else:
        print('\n'.join(_lines(doc)))
    return 0
