"""The one YAML loader of the suite: bounded in size, depth, aliases and expanded nodes.

Every YAML the suite reads comes from outside (a parameter file, a ``--param`` value, a bag's
``metadata.yaml``, the ``parameters_yaml`` of a BenchInfo, a recorded QoS profile) and goes
through :func:`load_yaml` / :func:`read_yaml_file`. ``yaml.safe_load`` executes nothing, but a
~1 KB alias bomb still expands to gigabytes once anything walks the result (a check, a repr
in an error message), and a deep nesting exhausts the stack. Here the event stream is
turned into Python objects by a small iterative constructor that counts, before anything
is built past a limit:

* bytes of text (checked before parsing),
* nesting depth,
* aliases (none at all in ROS parameter files: rcl refuses them, "Will not support aliasing"),
* expanded nodes: the size of the document with every alias expanded, so that no later walk
  of the result can take more than that.

Two scalar typings:

* ``'yaml'``: the YAML 1.1 types of ``yaml.safe_load`` (metadata.yaml and other data).
* ``'ros'``: the rules of rcl's parameter parser (``rcl_yaml_param_parser`` ``get_value``),
  which the nodes use on the files the launcher writes for them: quoted scalars are strings;
  plain ``true/yes/on/y`` (and capitalised forms) are booleans; what C ``strtol(s, 0)`` reads
  whole is an integer (``0x1f``, ``010`` octal); what ``strtod`` reads whole is a double
  (``1e5``, ``1.0e12``, ``inf``; YAML 1.1 would read ``1.0e12`` as a string); everything else
  (``null``, ``~``, ``1_000``, dates) is a string. An empty plain value is an error (rcl:
  "No value").
* ``'document'``: the suite's own documents (bench descriptions, test plans, tolerance
  profiles): ``'yaml'``, except that a plain scalar YAML 1.1 leaves as text but rcl reads as
  a number is that number (``1e4``, ``1.5e3``, ``5e-6``), so a value means the same in a
  plan as in a parameter file: one number rule everywhere.

Errors are :class:`~rv_te_bench.errors.YamlInputError` naming where (file and line) and
what; any value quoted in a message is cut to a few dozen characters (:func:`brief`).
"""

from __future__ import annotations

import math
import os
import re
import reprlib
import stat
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import yaml
from yaml.constructor import ConstructorError, SafeConstructor
from yaml.nodes import ScalarNode
from yaml.resolver import Resolver

from rv_te_bench.errors import YamlInputError, YamlLimitError

__all__ = [
    'BAG_METADATA_LIMITS', 'DOCUMENT_LIMITS', 'MAX_MESSAGE_CHARS', 'PARAMETER_FILE_LIMITS',
    'SMALL_TEXT_LIMITS', 'YamlLimits', 'brief', 'decode_text', 'dump_ros_yaml', 'load_yaml',
    'one_line', 'printable', 'read_yaml_file', 'ros_scalar',
]

_Loader = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)   # libyaml: ~20x faster events


@dataclass(frozen=True)
class YamlLimits:
    """Bounds on one YAML document.

    Attributes:
        max_bytes: Longest text [bytes, UTF-8].
        max_depth: Deepest nesting of mappings and sequences.
        max_aliases: Most ``*alias`` references (0: none allowed).
        max_nodes: Most nodes with every alias expanded (scalars, mappings, sequences).
    """

    max_bytes: int
    max_depth: int
    max_aliases: int
    max_nodes: int

    def __post_init__(self) -> None:
        """All limits are integers >= 0 (max_bytes, max_depth, max_nodes >= 1)."""
        for name in ('max_bytes', 'max_depth', 'max_aliases', 'max_nodes'):
            v = getattr(self, name)
            least = 0 if name == 'max_aliases' else 1
            if isinstance(v, bool) or not isinstance(v, int) or v < least:
                msg = f'YamlLimits.{name} must be an integer >= {least}, got {v!r}'
                raise ValueError(msg)


#: ROS parameter files (a session file is a few kB; 1 MiB is far beyond any real one).
PARAMETER_FILE_LIMITS = YamlLimits(max_bytes=1 << 20, max_depth=32, max_aliases=0,
                                   max_nodes=100_000)
#: One value on a command line or in a parameter (``--param``, ``--metadata``, a QoS string).
SMALL_TEXT_LIMITS = YamlLimits(max_bytes=64 << 10, max_depth=32, max_aliases=0,
                               max_nodes=10_000)
#: A document a user or a peer writes by hand (test plan, tolerance profile, bench program,
#: a BenchInfo's parameters_yaml): anchors allowed, bounded by the expanded size.
DOCUMENT_LIMITS = YamlLimits(max_bytes=1 << 20, max_depth=32, max_aliases=1000,
                             max_nodes=100_000)
#: A bag's metadata.yaml (rosbag2 writes no aliases; 10,000 split files are ~1.7 MB, read in
#: ~1.5 s; 4 MiB in ~3.5 s).
BAG_METADATA_LIMITS = YamlLimits(max_bytes=4 << 20, max_depth=32, max_aliases=1000,
                                 max_nodes=1_000_000)

_REPR = reprlib.Repr()
_REPR.maxstring = 60
_REPR.maxother = 60
_REPR.maxlist = _REPR.maxtuple = _REPR.maxset = _REPR.maxdict = 6
_REPR.maxlevel = 3
_BRIEF_MAX = 80


def brief(value: object) -> str:
    """``repr(value)`` cut to a few dozen characters, without walking all of ``value``.

    >>> brief('x' * 1000)[:12], len(brief('x' * 1000)) < 70
    ("'xxxxxxxxxxx", True)
    """
    text = _REPR.repr(value)
    return text if len(text) <= _BRIEF_MAX else text[:_BRIEF_MAX - 5] + '...' + text[-2:]


def decode_text(data: bytes, origin: str) -> str:
    """Bytes of a text file -> str: UTF-8, or UTF-16/32 with a byte-order mark (YAML 1.1).

    Raises:
        YamlInputError: Not decodable; names the first bad byte and its offset.
    """
    boms = ((b'\xff\xfe\x00\x00', 'utf-32-le'), (b'\x00\x00\xfe\xff', 'utf-32-be'),
            (b'\xff\xfe', 'utf-16-le'), (b'\xfe\xff', 'utf-16-be'), (b'\xef\xbb\xbf', 'utf-8'))
    encoding = 'utf-8'
    for bom, enc in boms:
        if data.startswith(bom):
            data, encoding = data[len(bom):], enc
            break
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as exc:
        bad = data[exc.start:exc.start + 1].hex()
        msg = (f'{origin} is not {encoding.upper()} text (byte 0x{bad} at offset {exc.start}); '
               'save it as UTF-8')
        raise YamlInputError(msg) from None


def read_yaml_file(path: str | Path, *, what: str, limits: YamlLimits,
                   scalars: Literal['yaml', 'ros', 'document'] = 'yaml',
                   unique_keys: bool = True,
                   ) -> Any:
    """Read and parse one YAML file within ``limits``.

    Only regular files are read (a FIFO or a device would block or never end), and never
    more than ``limits.max_bytes + 1`` bytes.

    Args:
        path: The file.
        what: What it is, for messages (``'parameter file'``).
        limits: Bounds (size, depth, aliases, expanded nodes).
        scalars: ``'yaml'`` (YAML 1.1, as safe_load), ``'ros'`` (rcl's parameter rules) or
            ``'document'`` (YAML 1.1 with rcl's numbers: the suite's own documents).
        unique_keys: Reject a mapping that repeats a key.

    Returns:
        The document (None when empty).

    Raises:
        YamlInputError: Unreadable, too large, not text, not valid YAML, or over a limit.
    """
    p = Path(path)
    origin = f'{what} {p}'
    try:
        # O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer, before
        # the check below could refuse it (regular files ignore the flag)
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | getattr(os, 'O_NOCTTY', 0))
        with os.fdopen(fd, 'rb') as f:
            if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
                msg = f'{origin}: not a regular file'
                raise YamlInputError(msg)
            data = f.read(limits.max_bytes + 1)
    except OSError as exc:
        msg = f'{origin}: cannot read ({exc.strerror or exc})'
        raise YamlInputError(msg) from None
    if len(data) > limits.max_bytes:
        msg = f'{origin} is larger than {_size(limits.max_bytes)}: not read'
        raise YamlLimitError(msg)
    return load_yaml(decode_text(data, origin), origin=origin, limits=limits, scalars=scalars,
                     unique_keys=unique_keys)


def _size(n: int) -> str:
    return f'{n >> 20} MiB' if n >= 1 << 20 else f'{n >> 10} KiB' if n >= 1 << 10 else f'{n} B'


def load_yaml(text: str | bytes, *, origin: str, limits: YamlLimits,
              scalars: Literal['yaml', 'ros', 'document'] = 'yaml',
              unique_keys: bool = True,
              ) -> Any:
    """Parse one YAML document within ``limits`` (see the module doc).

    Args:
        text: The document (bytes: UTF-8, or UTF-16/32 with a BOM).
        origin: Where it comes from, for messages (``'parameter file x.yaml'``).
        limits: Bounds (size, depth, aliases, expanded nodes).
        scalars: ``'yaml'``, ``'ros'`` or ``'document'`` scalar typing.
        unique_keys: Reject a mapping that repeats a key.

    Returns:
        The document (None when empty).

    Raises:
        YamlInputError: Not valid YAML, a tag other than YAML's own, a repeated key, or
            over a limit.
    """
    if isinstance(text, bytes | bytearray):
        if len(text) > limits.max_bytes:
            msg = f'{origin} is larger than {_size(limits.max_bytes)}: not read'
            raise YamlLimitError(msg)
        text = decode_text(bytes(text), origin)
    else:
        if len(text) > limits.max_bytes or len(text.encode('utf-8', 'surrogatepass')) \
                > limits.max_bytes:
            msg = f'{origin} is larger than {_size(limits.max_bytes)}: not read'
            raise YamlLimitError(msg)
        try:
            text.encode('utf-8')
        except UnicodeEncodeError as exc:
            msg = f'{origin} holds bytes that are not UTF-8 text (at character {exc.start})'
            raise YamlInputError(msg) from None
    try:
        return _Builder(origin, limits, scalars, unique_keys).run(text)
    except yaml.YAMLError as exc:
        detail = ' '.join(str(exc).split())
        if 'exceeded maximum nesting depth' in detail:
            # PyYAML >= 6.0.3 stops flow collections nested ~1000 deep while it scans ahead,
            # before our own count of the events sees the 33rd level
            msg = f'{origin}: nested deeper than {limits.max_depth} levels: not read'
            raise YamlLimitError(msg) from None
        msg = f'{origin}: not valid YAML ({detail[:300]})'
        raise YamlInputError(msg) from None


_STD = 'tag:yaml.org,2002:'
_SCALAR_TAGS = {f'{_STD}{t}' for t in ('str', 'int', 'float', 'bool', 'null', 'timestamp',
                                       'binary')}
_TRUE = {'Y', 'y', 'yes', 'Yes', 'YES', 'true', 'True', 'TRUE', 'on', 'On', 'ON'}
_FALSE = {'N', 'n', 'no', 'No', 'NO', 'false', 'False', 'FALSE', 'off', 'Off', 'OFF'}
# C strtol(s, &end, 0) reading all of s (no leading blanks in a plain YAML scalar)
_STRTOL = re.compile(r'[+-]?(?:0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)')
# C strtod reading all of s: decimal, hexadecimal, inf/infinity, nan/nan(chars)
_STRTOD_DEC = re.compile(r'[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?')
_STRTOD_HEX = re.compile(r'[+-]?0[xX](?:[0-9a-fA-F]+\.?[0-9a-fA-F]*|\.[0-9a-fA-F]+)'
                         r'(?:[pP][+-]?[0-9]+)?')
_STRTOD_SPECIAL = re.compile(r'([+-]?)(inf|infinity|nan(?:\([0-9A-Za-z_]*\))?)', re.IGNORECASE)
_YAML_SPECIAL = {'.nan': math.nan, '.NaN': math.nan, '.NAN': math.nan, '.inf': math.inf,
                 '.Inf': math.inf, '.INF': math.inf, '+.inf': math.inf, '+.Inf': math.inf,
                 '+.INF': math.inf, '-.inf': -math.inf, '-.Inf': -math.inf, '-.INF': -math.inf}
_INT64 = (-(1 << 63), (1 << 63) - 1)


def ros_scalar(value: str, *, quoted: bool) -> bool | int | float | str:
    """A scalar as rcl's parameter parser types it (rcl_yaml_param_parser ``get_value``).

    >>> ros_scalar('1.0e12', quoted=False), ros_scalar('0x10', quoted=False)
    (1000000000000.0, 16)
    >>> ros_scalar('yes', quoted=False), ros_scalar('yes', quoted=True)
    (True, 'yes')
    >>> ros_scalar('1_0', quoted=False), ros_scalar('null', quoted=False)
    ('1_0', 'null')
    """
    if quoted:
        return value
    if value in _TRUE:
        return True
    if value in _FALSE:
        return False
    if _STRTOL.fullmatch(value):
        body = value.lstrip('+-')
        neg = value.startswith('-')
        n = int(body, 16) if body[:2] in {'0x', '0X'} else int(body, 8) if body.startswith(
            '0') and len(body) > 1 else int(body)
        n = -n if neg else n
        if _INT64[0] <= n <= _INT64[1]:
            return n
        # out of range: strtol sets ERANGE, rcl then tries strtod
    if value in _YAML_SPECIAL:
        return _YAML_SPECIAL[value]
    number: float | None = None
    if _STRTOD_DEC.fullmatch(value):
        number = float(value)
        mantissa = re.split('[eE]', value)[0]
        underflow = (number == 0.0 and re.search('[1-9]', mantissa)) or (
            0.0 < abs(number) < sys.float_info.min)
        if math.isinf(number) or underflow:   # strtod sets ERANGE: rcl reads a string
            number = None
    elif _STRTOD_HEX.fullmatch(value):
        sign = -1.0 if value.startswith('-') else 1.0
        body = value.lstrip('+-')
        try:
            number = sign * float.fromhex(body if any(c in body for c in '.pP') else body + 'p0')
        except OverflowError:
            number = None
    elif m := _STRTOD_SPECIAL.fullmatch(value):
        base = math.nan if m.group(2).lower().startswith('nan') else math.inf
        number = -base if m.group(1) == '-' else base
    return value if number is None else number


class _Builder:
    """Events -> Python objects, iteratively, counting depth, aliases and expanded nodes."""

    def __init__(self, origin: str, limits: YamlLimits, scalars: str, unique_keys: bool,
                 ) -> None:
        self.origin = origin
        self.limits = limits
        self.ros = scalars == 'ros'
        self.document = scalars == 'document'
        self.unique_keys = unique_keys
        self.resolver = Resolver()
        self.constructor = SafeConstructor()
        self.anchors: dict[str, tuple[Any, int]] = {}   # anchor -> (object, expanded size)
        self.open_anchors: set[str] = set()
        self.aliases = 0
        self.nodes = 0

    def fail(self, event: Any, text: str,   # Any: a yaml.Event; start_mark read via getattr
             kind: type[YamlInputError] = YamlInputError) -> YamlInputError:
        line = event.start_mark.line + 1 if getattr(event, 'start_mark', None) else '?'
        return kind(f'{self.origin}, line {line}: {text}')

    def count(self, event: yaml.Event, n: int) -> None:
        self.nodes += n
        if self.nodes > self.limits.max_nodes:
            msg = (f'more than {self.limits.max_nodes} YAML nodes (aliases expanded): '
                   'not read')
            raise self.fail(event, msg, YamlLimitError)

    def run(self, text: str) -> Any:
        # stack entries: [container, anchor, expanded size, pending key, has key, start event]
        stack: list[list[Any]] = []
        root: Any = None
        documents = 0
        for event in yaml.parse(text, Loader=_Loader):
            if isinstance(event, yaml.DocumentStartEvent):
                documents += 1
                if documents > 1:
                    raise self.fail(event, 'more than one YAML document')
                continue
            if isinstance(event, yaml.StreamStartEvent | yaml.StreamEndEvent
                          | yaml.DocumentEndEvent):
                continue
            if isinstance(event, yaml.MappingStartEvent | yaml.SequenceStartEvent):
                self.check_tag(event, 'map' if isinstance(event, yaml.MappingStartEvent)
                               else 'seq')
                if len(stack) >= self.limits.max_depth:
                    msg = f'nested deeper than {self.limits.max_depth} levels: not read'
                    raise self.fail(event, msg, YamlLimitError)
                self.count(event, 1)
                container: Any = {} if isinstance(event, yaml.MappingStartEvent) else []
                if event.anchor:
                    self.open_anchors.add(event.anchor)
                stack.append([container, event.anchor, 1, None, False, event])
                continue
            if isinstance(event, yaml.MappingEndEvent | yaml.SequenceEndEvent):
                container, anchor, size, _, _, _ = stack.pop()
                if anchor:
                    self.open_anchors.discard(anchor)
                    self.anchors[anchor] = (container, size)
                value, size_ = container, size
            elif isinstance(event, yaml.AliasEvent):
                self.aliases += 1
                if self.aliases > self.limits.max_aliases:
                    msg = ('YAML aliases (*name) are not allowed here' if not
                           self.limits.max_aliases else
                           f'more than {self.limits.max_aliases} YAML aliases: not read')
                    raise self.fail(event, msg, YamlLimitError)
                if event.anchor in self.open_anchors:
                    raise self.fail(event, f'alias *{brief(event.anchor)} refers to itself')
                if event.anchor not in self.anchors:
                    raise self.fail(event, f'undefined alias *{brief(event.anchor)}')
                value, size_ = self.anchors[event.anchor]
                self.count(event, size_)
            else:   # scalar; a mapping key of a ROS parameter file stays the text (rcl)
                assert isinstance(event, yaml.ScalarEvent)  # the only event left
                self.count(event, 1)
                is_key = bool(stack) and isinstance(stack[-1][0], dict) and not stack[-1][4]
                value, size_ = self.scalar(event, key=is_key), 1
                if event.anchor:
                    self.anchors[event.anchor] = (value, 1)
            if not stack:
                root = value
                continue
            top = stack[-1]
            top[2] += size_
            if isinstance(top[0], list):
                top[0].append(value)
            elif not top[4]:
                if isinstance(value, dict | list):
                    raise self.fail(event, 'a mapping key must be a scalar')
                if self.unique_keys and value in top[0]:
                    raise self.fail(event, f'key {brief(value)} appears twice in one mapping')
                top[3], top[4] = value, True
            else:
                top[0][top[3]] = value
                top[3], top[4] = None, False
        return root

    def check_tag(self, event: yaml.CollectionStartEvent, kind: str) -> None:
        tag = event.tag
        if tag in (None, '!', f'{_STD}{kind}'):
            return
        raise self.fail(event, f'not valid YAML data: tag {brief(tag)} is not allowed')

    def scalar(self, event: Any, *, key: bool) -> Any:   # Any: types-PyYAML's two Mark types
        tag = event.tag
        plain = bool(event.implicit[0]) and not event.style
        if tag not in (None, '!') and tag not in _SCALAR_TAGS:
            raise self.fail(event, f'not valid YAML data: tag {brief(tag)} is not allowed')
        if self.ros:
            if tag not in (None, '!'):
                raise self.fail(event, f'not valid YAML for ROS: tag {brief(tag)} (rcl ignores '
                                       'tags; quote a string instead)')
            if plain and event.value == '':
                raise self.fail(event, f'no {"key" if key else "value"} (rcl needs one)')
            return event.value if key else ros_scalar(event.value, quoted=not plain)
        if tag in (None, '!'):
            tag = self.resolver.resolve(ScalarNode, event.value, event.implicit)  # type: ignore[no-untyped-call]  # untyped in types-PyYAML
            if self.document and plain and not key and tag == f'{_STD}str':
                number = ros_scalar(event.value, quoted=False)   # rcl's numbers (1e4)
                if isinstance(number, int | float) and not isinstance(number, bool):
                    return number
        try:
            return self.constructor.construct_object(ScalarNode(tag, event.value,
                                                                event.start_mark))
        except (ConstructorError, ValueError) as exc:
            raise self.fail(event, f'bad {tag.rsplit(":", 1)[-1]} {brief(event.value)} '
                                   f'({" ".join(str(exc).split())[:80]})') from None


class _RosDumper(yaml.SafeDumper):
    """Every string double-quoted (rcl would read a plain ``y``, ``1e5`` or ``on`` as a bool or
    number), no anchors or aliases (rcl refuses them)."""

    def ignore_aliases(self, data: object) -> bool:
        return True


def _quoted_str(dumper: yaml.SafeDumper, data: str) -> yaml.ScalarNode:
    return dumper.represent_scalar('tag:yaml.org,2002:str', data, style='"')


_RosDumper.add_representer(str, _quoted_str)


def dump_ros_yaml(data: object) -> str:
    """YAML that rcl's parameter parser and :func:`load_yaml` read back to ``data`` exactly."""
    return yaml.dump(data, Dumper=_RosDumper, sort_keys=True, allow_unicode=True,
                     default_flow_style=False)


def printable(text: object) -> str:
    """``str(text)`` with undecodable bytes (surrogates from a non-UTF-8 path or argument)
    shown as U+FFFD, so that fonts, HTML and UTF-8 writers take it."""
    return str(text).encode('utf-8', 'surrogateescape').decode('utf-8', 'replace')


#: Longest message a command prints for one error [characters].
MAX_MESSAGE_CHARS = 600


def one_line(message: object, limit: int = MAX_MESSAGE_CHARS) -> str:
    """An error message as one line of at most ``limit`` characters (values in messages can
    come from files of any size: the middle is cut, the length stated)."""
    text = ' '.join(str(message).split())
    if len(text) <= limit:
        return text
    keep = limit - 40
    return f'{text[:keep * 2 // 3]} [... {len(text) - keep} characters cut ...] ' \
           f'{text[-(keep // 3):]}'
