"""What a bench recorded about itself: the BenchInfo record, one shape, read back bounded.

* :func:`read_bench_info`: the last BenchInfo of a bag (through the summary's chunk index
  when the file has one), as the one in-memory record of it, :class:`sim.bench_info.BenchInfoData`;
  :func:`bench_info_cdr` the other way: a record as the message's CDR bytes, for bags
  written without ROS (``rv-te import``, ``bags/make_sample.py``);
* :func:`overrides_from_parameters_yaml` and :func:`preset_from_bench_info`: the preset a
  bench ran with, rebuilt from its ``parameters_yaml``. The text comes from a bag or from
  the network: it is parsed by the suite's bounded loader (:mod:`rv_te_bench.safe_yaml`),
  so a hostile record costs at most its limits.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.core.bench_uncertainty import BenchUncertainty, bench_uncertainty_from_plain
from rv_te_bench.errors import BagError, BenchInfoError, TeConfigError, YamlInputError
from rv_te_bench.io._bag_open import find_messages, open_bag, scan_topics, topic_types
from rv_te_bench.io._bag_types import MessageStream, summarize_problems
from rv_te_bench.io.msgdefs import BENCH_INFO, ENCODER_BLOCK, own_typestore, rv_te_typestore
from rv_te_bench.safe_yaml import DOCUMENT_LIMITS, load_yaml
from sim.bench_info import BenchInfoData

if TYPE_CHECKING:
    from collections.abc import Sequence
    from pathlib import Path

    from rv_te_bench.core.te_zero import EncoderZero
    from sim.presets import Preset

__all__ = ['PARAMETERS_YAML_LIMITS', 'bench_info_cdr', 'bench_uncertainty_of', 'encoder_zero_of',
           'overrides_from_parameters_yaml',
           'preset_from_bench_info', 'read_bench_info', 'uncertainty_from_parameters_yaml']

#: A BenchInfo record holds the preset's values and the bench settings: a few kB.
PARAMETERS_YAML_LIMITS = DOCUMENT_LIMITS


@functools.lru_cache(maxsize=8)
def _parsed_parameters(text: str) -> Any:
    """``parameters_yaml`` parsed once per text (an analysis reads it three times: zeros,
    uncertainty, preset; ~1.2 ms each, issue 41). Raises YamlInputError as load_yaml."""
    return load_yaml(text, origin='BenchInfo.parameters_yaml', limits=PARAMETERS_YAML_LIMITS)


def _parameters_record(text: str) -> Any:
    """A private copy of the parsed ``parameters_yaml`` (callers may change theirs)."""
    return copy.deepcopy(_parsed_parameters(text))


def overrides_from_parameters_yaml(text: str) -> list[str]:
    """The preset overrides a bench ran with, from ``BenchInfoData.parameters_yaml``.

    The inverse of what :attr:`sim.bench.BenchSimulator.info` records (``bench.overrides``),
    so that a consumer of a live BenchInfo or of a bag can rebuild the bench's exact preset.
    Anything unreadable, over the limits or not a list of scalars gives ``[]`` (the base
    preset).
    """
    if not text:
        return []
    try:
        record = _parameters_record(text)
    except YamlInputError:
        return []
    bench = record.get('bench') if isinstance(record, dict) else None
    overrides = bench.get('overrides') if isinstance(bench, dict) else None
    if not isinstance(overrides, list) or not all(
            isinstance(o, str | int | float) for o in overrides):
        return []
    return [str(o) for o in overrides]


def uncertainty_from_parameters_yaml(text: str) -> Any:
    """The bench description's ``uncertainty:`` section a bench recorded in
    ``BenchInfoData.parameters_yaml`` (``bench.uncertainty``; the mapping as written, to be
    checked by :func:`rv_te_bench.core.bench_uncertainty.bench_uncertainty_from_plain`),
    or None when there is none or the text is unreadable."""
    if not text:
        return None
    try:
        record = _parameters_record(text)
    except YamlInputError:
        return None
    bench = record.get('bench') if isinstance(record, dict) else None
    return bench.get('uncertainty') if isinstance(bench, dict) else None


def bench_uncertainty_of(info: BenchInfoData | None) -> tuple[BenchUncertainty, list[str]]:
    """The bench's error model: data-sheet defaults of its encoders, with the bench
    description's ``uncertainty:`` section (recorded in BenchInfo ``parameters_yaml``)
    over them. Returns (model, notes): a section that does not parse is named in a note
    and the defaults are used."""
    if info is None:
        return BenchUncertainty.defaults('', ''), [
            'the bag has no BenchInfo: encoder models unknown, only what the data shows']
    base = BenchUncertainty.defaults(
        info.encoder_in_model, info.encoder_out_model,
        resolution_in_rad=info.encoder_in_resolution_rad,
        resolution_out_rad=info.encoder_out_resolution_rad)
    section = uncertainty_from_parameters_yaml(info.parameters_yaml)
    if section is None:
        return base, []
    try:
        return bench_uncertainty_from_plain(
            section, base, where='BenchInfo parameters_yaml bench.uncertainty'), []
    except TeConfigError as exc:
        return base, [f'the bench description\'s uncertainty section is not used: {exc}']


def encoder_zero_of(info: BenchInfoData | None) -> EncoderZero | None:
    """The encoder zeros a bench record declares (``parameters_yaml``), or None.

    :func:`rv_te_bench.core.te_zero.encoder_zero_from_record` reads the parsed record; an
    unreadable ``parameters_yaml`` declares nothing.
    """
    from rv_te_bench.core.te_zero import encoder_zero_from_record

    if info is None or not info.parameters_yaml:
        return None
    try:
        record = _parameters_record(info.parameters_yaml)
    except YamlInputError:
        return None
    return encoder_zero_from_record(record)


def preset_from_bench_info(info: BenchInfoData, extra_overrides: Sequence[str] = ()) -> Preset:
    """The preset a bench ran with: its preset with the overrides it recorded, then ``extra``.

    Raises:
        PresetError: Unknown preset or a bad override (``sim.errors``).
    """
    from sim.presets import load_preset

    return load_preset(info.preset, [*overrides_from_parameters_yaml(info.parameters_yaml),
                                     *extra_overrides])


def read_bench_info(path: str | Path, topic: str | None = None) -> BenchInfoData | None:
    """The last BenchInfo message of a bag as its record, or None if there is none.

    Args:
        path: Bag folder or ``.mcap`` file.
        topic: BenchInfo topic; None: every topic of type BenchInfo.

    Raises:
        BenchInfoError: The bag's encoder data is there but BenchInfo is damaged or does not
            deserialise (the command line's ratio / preset can stand in for it).
        BagError: Bad layout, or not a readable MCAP bag (no topic, or neither BenchInfo
            nor encoder data readable).
    """
    bag = open_bag(path)
    types = topic_types(bag)
    if not types:
        text = (f'{bag.path} is not a readable MCAP bag: no topic in it (not a bag, or '
                'truncated before its first message)')
        raise BagError(text)
    names = [topic] if topic is not None else [t for t, ty in types.items() if ty == BENCH_INFO]
    if not names:
        return None
    last: bytes | None = None
    stream: MessageStream[Any] = MessageStream(lambda s: iter(()), strict=False)
    for msgtype, data in find_messages(bag, stream, names):
        if msgtype == BENCH_INFO:
            last = data
    if last is None:
        if stream.partial:   # the BenchInfo may be in the part that cannot be read
            damage = summarize_problems(stream.problems).rstrip('.')
            if ENCODER_BLOCK not in {t['type'] for t in scan_topics(bag).values()}:
                # nothing the command line could replace BenchInfo for (issue #21)
                text = (f'{bag.path} is not a readable MCAP bag: neither BenchInfo nor '
                        f'encoder data can be read: {damage}')
                raise BagError(text)
            text = f'Bag {bag.path}: no readable BenchInfo; the bag is damaged: {damage}'
            raise BenchInfoError(text)
        return None
    try:
        from rv_te_bench.io._legacy_msgs import upgrade_cdr

        return BenchInfoData.from_message(
            rv_te_typestore().deserialize_cdr(upgrade_cdr(BENCH_INFO, last), BENCH_INFO))
    except Exception as exc:  # noqa: BLE001
        text = f'Bag {bag.path}: BenchInfo does not deserialise: {str(exc).rstrip(".")}'
        raise BenchInfoError(text) from None


#: BenchInfo's float64[] fields (rosbags serialises primitive arrays from numpy only).
_FLOAT_ARRAYS = frozenset(f.name for f in dataclasses.fields(BenchInfoData)
                          if f.type == 'tuple[float, ...]')
_NS = 1_000_000_000


def bench_info_cdr(info: BenchInfoData, stamp_ns: int) -> bytes:
    """``info`` as one serialised ``rv_te_msgs/BenchInfo`` (CDR), as the bench node sends it.

    The header is stamped ``stamp_ns`` with the bench id as its frame. Every field comes
    from the record (:meth:`~sim.bench_info.BenchInfoData.message_values`, each value
    converted to its declared type first): a field added to the record and the message is
    written without a change here. :func:`read_bench_info` reads it back.
    """
    store = own_typestore(BENCH_INFO)   # rv_te_typestore's bytes, 0.1 CPU s less to build
    types = store.types
    values = BenchInfoData.from_message(info).message_values()
    for name in _FLOAT_ARRAYS:
        values[name] = np.asarray(values[name], dtype=np.float64)
    header = types['std_msgs/msg/Header'](
        stamp=types['builtin_interfaces/msg/Time'](sec=stamp_ns // _NS, nanosec=stamp_ns % _NS),
        frame_id=info.bench_id)
    return bytes(store.serialize_cdr(types[BENCH_INFO](header=header, **values), BENCH_INFO))
