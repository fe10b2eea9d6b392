"""Message definitions of rv_te_msgs for bags, found and parsed without rclpy.

rosbag2 stores, for every topic type, the full ``ros2msg`` definition: the type's own
``.msg`` text followed by each dependency as ``====...====\\nMSG: pkg/msg/Type\\n<text>``.
This module builds the same text from the ``.msg`` files (installed share directory first,
then the repository's ``rv_te_msgs_py/msg``), falling back to the rosbags typestore for
dependencies that have no ``.msg`` file on this machine, and offers a rosbags typestore
(``Stores.ROS2_JAZZY`` plus our types) for serialising and deserialising without ROS.
"""

from __future__ import annotations

import functools
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from rv_te_bench.errors import BagError

if TYPE_CHECKING:
    from rosbags.interfaces.typing import FieldDesc, Typesdict
    from rosbags.typesys.store import Typestore

__all__ = [
    'BENCH_CHANNELS',
    'BENCH_INFO',
    'ENCODER_BLOCK',
    'MSG_PACKAGE',
    'find_msg_dir',
    'full_msgdef',
    'learn_type',
    'load_msg_texts',
    'own_typestore',
    'rv_te_typestore',
    'type_hash',
]

MSG_PACKAGE = 'rv_te_msgs'
ENCODER_BLOCK = 'rv_te_msgs/msg/EncoderBlock'
BENCH_INFO = 'rv_te_msgs/msg/BenchInfo'
BENCH_CHANNELS = 'rv_te_msgs/msg/BenchChannels'

SEPARATOR = '=' * 80


def _share_dirs() -> list[Path]:
    """Candidate ``share`` directories: the venv prefix, the base prefix, then every prefix
    of ``AMENT_PREFIX_PATH`` (a sourced ROS 2 install or colcon workspace)."""
    prefixes = [sys.prefix, sys.base_prefix,
                *(p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p)]
    return [Path(p) / 'share' for p in dict.fromkeys(prefixes)]


def find_msg_dir() -> Path:
    """Directory holding the ``rv_te_msgs`` ``.msg`` files.

    Returns:
        ``<sys.prefix>/share/rv_te_msgs/msg`` when installed, else the repository's
        ``rv_te_msgs_py/msg`` next to the ``rv_te_bench`` package.

    Raises:
        BagError: Neither location holds ``.msg`` files.
    """
    candidates = [d / MSG_PACKAGE / 'msg' for d in _share_dirs()]
    candidates.append(Path(__file__).resolve().parents[2] / 'rv_te_msgs_py' / 'msg')
    for cand in candidates:
        if cand.is_dir() and any(cand.glob('*.msg')):
            return cand
    msg = f'No {MSG_PACKAGE} .msg files found; looked in {[str(c) for c in candidates]}.'
    raise BagError(msg)


@functools.cache
def load_msg_texts() -> dict[str, str]:
    """Texts of our ``.msg`` files keyed by full type name (``rv_te_msgs/msg/Name``)."""
    msg_dir = find_msg_dir()
    return {
        f'{MSG_PACKAGE}/msg/{p.stem}': p.read_text(encoding='utf-8')
        for p in sorted(msg_dir.glob('*.msg'))
    }


@functools.cache
def rv_te_typestore() -> Typestore:
    """A rosbags typestore: ROS 2 Jazzy types plus every ``rv_te_msgs`` type."""
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for name, text in load_msg_texts().items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


#: The ROS 2 types that rv_te_msgs use (std_msgs/Header and its stamp), as Jazzy defines
#: them (tested equal to the rosbags Jazzy store's definitions).
BASE_MSG_TEXTS = {'builtin_interfaces/msg/Time': 'int32 sec\nuint32 nanosec\n',
                  'std_msgs/msg/Header': 'builtin_interfaces/Time stamp\nstring frame_id\n'}


@functools.cache
def _own_store() -> Typestore:
    return get_typestore(Stores.EMPTY)


def own_typestore(*msgtypes: str) -> Typestore:
    """A small rosbags typestore of ``rv_te_msgs`` types and the two ROS 2 types they use,
    without the Jazzy store (building that costs ~0.1 CPU s per process: every ``rv-te
    import`` paid it, issue 41). Serialises our messages to the same bytes and gives the
    same definitions and type hashes as :func:`rv_te_typestore` (tested).

    Args:
        msgtypes: Types to make known (each parsed once per process, with the types it
            uses); none: all of ``rv_te_msgs``.

    Raises:
        BagError: A type that is not ours, or uses a type that is not (``_known_in``).
    """
    store = _own_store()
    texts = {**BASE_MSG_TEXTS, **load_msg_texts()}
    todo = list(msgtypes or texts)
    found: Typesdict = {}
    while todo:
        name = todo.pop()
        if name in store.fielddefs or name in found:
            continue
        if name not in texts:
            msg = f'{name!r} is not an rv_te_msgs type nor one they use'
            raise BagError(msg)
        parsed = get_types_from_msg(texts[name], name)
        found.update(parsed)
        for _, node in parsed[name][1]:
            todo.extend(_referenced(node))
    if found:
        store.register(found)
    return store


def _known_in(msgtype: str) -> bool:
    """``msgtype`` is ours and uses only our types and those of BASE_MSG_TEXTS."""
    try:
        own_typestore(msgtype)
    except BagError:
        return False
    return True


def _store_for(msgtype: str) -> Typestore:
    """:func:`own_typestore` for our types, else :func:`rv_te_typestore` (taught the type)."""
    if msgtype in load_msg_texts() and _known_in(msgtype):
        return own_typestore(msgtype)
    store = rv_te_typestore()
    learn_type(msgtype)
    return store


def _msg_file_text(msgtype: str) -> str | None:
    """Text of ``msgtype``'s ``.msg`` file if one is installed here."""
    if msgtype in (ours := load_msg_texts()):
        return ours[msgtype]
    pkg, _, name = msgtype.split('/')
    for share in _share_dirs():
        path = share / pkg / 'msg' / f'{name}.msg'
        if path.is_file():
            return path.read_text(encoding='utf-8')
    return None


@functools.cache
def full_msgdef(msgtype: str) -> str:
    """Full ``ros2msg`` definition of ``msgtype`` as rosbag2 stores it in a bag.

    Args:
        msgtype: Type name, ``pkg/msg/Name``.

    Returns:
        The type's text followed by every dependency after a separator line.

    Raises:
        BagError: The type is unknown to the typestore.
    """
    return full_msgdef_from(_store_for(msgtype), msgtype)


def full_msgdef_from(store: Typestore, msgtype: str) -> str:
    """:func:`full_msgdef` with the definitions of ``store`` (which knows ``msgtype``)."""
    subdefs: dict[str, tuple[str, str]] = {}
    generated, _ = store.gendefhash(msgtype, subdefs, ros_version=2)
    parts = [(_msg_file_text(msgtype) or generated).rstrip('\n') + '\n']
    for dep, (dep_text, _) in subdefs.items():
        text = _msg_file_text(dep) or dep_text
        short = dep.replace('/msg/', '/')
        parts.append(f'{SEPARATOR}\nMSG: {short}\n{text.rstrip(chr(10))}\n')
    return ''.join(parts)


def type_hash(msgtype: str) -> str:
    """RIHS01 type hash of ``msgtype`` (equal to what rclpy reports for the type)."""
    return _store_for(msgtype).hash_rihs01(msgtype)


def _referenced(node: FieldDesc) -> list[str]:
    """Type names a rosbags field definition refers to (also inside arrays/sequences)."""
    if node[0] == Nodetype.NAME:
        return [node[1]]
    if node[0] == Nodetype.ARRAY or node[0] == Nodetype.SEQUENCE:
        return _referenced(node[1][0])
    return []


def learn_type(msgtype: str) -> None:
    """Make ``msgtype`` known to :func:`rv_te_typestore`, with its dependencies.

    Types outside ROS 2 Jazzy's standard set and ``rv_te_msgs`` (a vendor's message on the
    bench) are read from their installed ``.msg`` files (``share/<pkg>/msg``, also under
    ``AMENT_PREFIX_PATH``) and registered, so that they can be recorded with their full
    definition.

    Raises:
        BagError: No definition of the type (or of a type it uses) on this machine.
    """
    store = rv_te_typestore()
    todo = [msgtype]
    found: Typesdict = {}
    while todo:
        name = todo.pop()
        if name in store.fielddefs or name in found:
            continue
        parts = name.split('/')
        text = _msg_file_text(name) if len(parts) == 3 else None
        if text is None:
            where = ', '.join(str(d) for d in _share_dirs())
            msg = (f'Unknown message type {name!r}'
                   + (f' (used by {msgtype!r})' if name != msgtype else '')
                   + f': not a standard ROS 2 Jazzy type and no .msg file under {where}.')
            raise BagError(msg)
        try:
            parsed = get_types_from_msg(text, name)
        except Exception as exc:  # noqa: BLE001 - rosbags raises its own parse errors
            msg = f'Cannot parse the .msg file of {name!r}: {exc}'
            raise BagError(msg) from None
        found.update(parsed)
        for _, node in parsed[name][1]:
            todo.extend(_referenced(node))
    if found:
        store.register(found)
