"""Message definitions of rv_te_msgs before issue 36, so that older bags stay readable.

Issue 36 appended fields to ``EncoderBlock`` (read heads) and ``BenchInfo`` (scales and
heads). Bags recorded before carry the older definitions (their type hashes are
:data:`LEGACY_HASHES`); the fields that exist in both are the same bytes, the new ones are
absent. :func:`upgrade_cdr` turns such a message into today's layout (new fields at their
defaults: empty, '' or 0), which is what replay publishes and what the generic decoders
read; the hand-written EncoderBlock decoder reads both layouts directly.
"""

from __future__ import annotations

import functools
from importlib import resources
from typing import TYPE_CHECKING

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from rv_te_bench.io.msgdefs import BENCH_INFO, ENCODER_BLOCK, rv_te_typestore

if TYPE_CHECKING:
    from rosbags.interfaces.typing import FieldDesc, Typesdict
    from rosbags.typesys.store import Typestore

__all__ = ['LEGACY_HASHES', 'added_field_defaults', 'legacy_typestore', 'upgrade_cdr']

#: The older definitions, as shipped in ``legacy_msgs/`` (the .msg texts of before issue 36).
_FILES = {ENCODER_BLOCK: 'EncoderBlock_v0.msg', BENCH_INFO: 'BenchInfo_v0.msg'}


#: RIHS01 hashes of the definitions before issue 36 (what older bags' metadata names).
LEGACY_HASHES: dict[str, frozenset[str]] = {
    ENCODER_BLOCK: frozenset({
        'RIHS01_1229821431777e90a6034a2640f4811afa7b42cdd596471fe57b8be9481d6c4d'}),
    BENCH_INFO: frozenset({
        'RIHS01_70dc6146a20e1f3b021c9b89272649bbef4b07765546494d42b02a5a0f9cbcfa'}),
}


@functools.cache
def legacy_typestore() -> Typestore:
    """A rosbags typestore with the pre-issue-36 definitions under their own names."""
    store = get_typestore(Stores.ROS2_JAZZY)
    types: Typesdict = {}
    here = resources.files('rv_te_bench.io').joinpath('legacy_msgs')
    for name, file in _FILES.items():
        types.update(get_types_from_msg(here.joinpath(file).read_text('utf-8'), name))
    store.register(types)
    return store


def _default(node: FieldDesc) -> np.ndarray | str | float:
    """The default of a field issue 36 added (rosbags field definition)."""
    kind, detail = node
    if getattr(kind, 'name', '') == 'SEQUENCE':
        base = detail[0][1][0]
        return np.zeros(0, dtype=np.uint8 if base == 'uint8' else np.float64)
    return '' if detail[0] == 'string' else 0.0


def added_field_defaults(msgtype: str) -> dict[str, np.ndarray | str | float]:
    """The fields issue 36 added to ``msgtype`` at their defaults ("not stated"), for
    building a message with rosbags' typestore, which needs every field."""
    if msgtype not in _FILES:
        return {}
    old = {name for name, _ in legacy_typestore().fielddefs[msgtype][1]}
    return {name: _default(node) for name, node in rv_te_typestore().fielddefs[msgtype][1]
            if name not in old}


def upgrade_cdr(msgtype: str, data: bytes | memoryview) -> bytes:
    """An older ``msgtype`` message (CDR) in today's layout; today's messages unchanged.

    Raises:
        Exception: The bytes are neither layout (rosbags' own errors).
    """
    raw = bytes(data)
    if msgtype not in _FILES:
        return raw
    new = rv_te_typestore()
    try:
        new.deserialize_cdr(raw, msgtype)
        current = True
    except Exception:  # noqa: BLE001 - not today's layout: try the older one
        current = False
    if current:
        return raw
    old = legacy_typestore().deserialize_cdr(raw, msgtype)
    cls = new.types[msgtype]
    values = {}
    for name, node in new.fielddefs[msgtype][1]:
        values[name] = getattr(old, name) if hasattr(old, name) else _default(node)
    return bytes(new.serialize_cdr(cls(**values), msgtype))
