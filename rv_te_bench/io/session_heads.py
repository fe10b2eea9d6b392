"""What a session's TE node did with the read heads, read back from its bag.

The TE node publishes, latched on ``te/encoder_heads`` (recorded by default), a YAML record
of how it formed each shaft's angle: the head layout, the mode, and the encoder calibration
it took off the readings (``{'output': {'mode', 'layout', 'calibration', ...}, 'input':
..., 'problem': ...}``). :func:`session_calibration` gives the output scale's calibration of
that record, so that an offline analysis of the bag forms the same angle the live TE did
(and says so) instead of silently reading the uncalibrated head.

The text comes from a bag: parsed by the suite's bounded loader; a record that cannot be
read is reported in one line and the bag is analysed without it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from rv_te_bench.errors import BagError, EncoderCalibrationError, RvTeError, YamlInputError
from rv_te_bench.io._bag_open import find_messages, open_bag, topic_types
from rv_te_bench.io._bag_types import MessageStream
from rv_te_bench.safe_yaml import DOCUMENT_LIMITS, load_yaml

if TYPE_CHECKING:
    import datetime
    from pathlib import Path

    from rv_te_bench.core.encoder_calibration import EncoderCalibration
    from sim.bench_info import BenchInfoData

__all__ = ['HEADS_TOPIC', 'SessionCalibration', 'choose_calibration', 'session_calibration',
           'session_heads_record']

#: The TE node's record topic (relative: a namespaced session records ``/ns/te/encoder_heads``).
HEADS_TOPIC = 'te/encoder_heads'
_STRING = 'std_msgs/msg/String'


def session_heads_record(path: str | Path) -> dict[str, Any] | None:
    """The last ``te/encoder_heads`` record of a bag (None: the bag has none).

    Raises:
        BagError: Bad layout, or a record that does not decode or is not a YAML mapping
            (one line naming the bag).
    """
    bag = open_bag(path)
    names = [t for t, ty in topic_types(bag).items()
             if ty == _STRING and (t == HEADS_TOPIC or t.endswith('/' + HEADS_TOPIC))]
    if not names:
        return None
    last: bytes | None = None
    stream: MessageStream[Any] = MessageStream(lambda s: iter(()), strict=False)
    for _msgtype, data in find_messages(bag, stream, names):
        last = bytes(data)
    if last is None:
        return None
    from rosbags.typesys import Stores, get_typestore

    try:
        decoded: Any = get_typestore(Stores.ROS2_JAZZY).deserialize_cdr(last, _STRING)
        text = decoded.data   # a class the typestore generates at run time
        record = load_yaml(text, origin=f'{bag.path}: {HEADS_TOPIC}', limits=DOCUMENT_LIMITS)
    except YamlInputError as exc:
        raise BagError(str(exc)) from None
    except Exception as exc:  # noqa: BLE001 - rosbags' own errors: one line
        msg = f'{bag.path}: {HEADS_TOPIC} does not deserialise: {str(exc).rstrip(".")}'
        raise BagError(msg) from None
    if not isinstance(record, dict):
        msg = f'{bag.path}: {HEADS_TOPIC} is not a mapping ({type(record).__name__})'
        raise BagError(msg)
    return record


class SessionCalibration:
    """The output calibration a session's TE node applied, or why none is taken from it.

    Attributes:
        calibration: The calibration (None: the session applied none, or it is unreadable).
        problem: Why a record was there but gave no calibration ('' otherwise).
    """

    def __init__(self, calibration: EncoderCalibration | None, problem: str = '') -> None:
        self.calibration = calibration
        self.problem = problem


def session_calibration(path: str | Path) -> SessionCalibration:
    """The output scale's calibration the bag's TE node applied (never raises: a damaged
    record is reported in :attr:`SessionCalibration.problem`)."""
    from rv_te_bench.core.encoder_calibration import calibration_from_plain

    try:
        record = session_heads_record(path)
    except BagError as exc:
        return SessionCalibration(None, str(exc))
    out = (record or {}).get('output')
    plain = out.get('calibration') if isinstance(out, dict) else None
    if not plain:
        return SessionCalibration(None)
    try:
        return SessionCalibration(calibration_from_plain(plain, f'{path}: {HEADS_TOPIC}'))
    except RvTeError as exc:
        return SessionCalibration(None, str(exc))


def choose_calibration(path: str | Path, info: BenchInfoData | None,
                       given: EncoderCalibration | None, *, from_session: bool = True,
                       when: datetime.date | None = None,
                       ) -> tuple[EncoderCalibration | None, str, list[str]]:
    """The output calibration an offline analysis of ``path`` applies.

    Returns:
        ``(calibration, source, problems)``: the one ``given`` (source ``'file'``); else,
        with ``from_session``, the one the session's TE node applied live when it still
        holds for the bag's scale on the session's day ``when`` (source ``'session'``);
        else None and ``''``. ``problems``: why a session record was not used (one line
        each; the analysis goes on without it).
    """
    if given is not None:
        return given, 'file', []
    if not from_session or info is None:
        return None, '', []
    found = session_calibration(path)
    problems = ([f"the session's encoder-heads record is not used: {found.problem}"]
                if found.problem else [])
    cal = found.calibration
    if cal is None:
        return None, '', problems
    try:
        cal.check_for(info.encoder_out_scale_serial, when=when)
    except EncoderCalibrationError as exc:
        problems.append(f"the calibration the session's TE node applied is left out: {exc}")
        return None, '', problems
    return cal, 'session', problems
