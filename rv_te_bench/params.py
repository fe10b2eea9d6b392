"""Node parameter specifications, shared by the nodes and the launcher (no rclpy here).

Each node lists its parameters once, as the fields of a frozen record (``generate_parameter
_library``'s typed ``Params`` struct, in Python): ``rate_hz: float = param(10.0, 'Rate [Hz]',
min_value=1.0)``. :func:`param_specs` turns the record into :class:`ParamSpec` items: the
node declares them with descriptors (description with unit, range, read-only), and the
launcher checks a ROS-style parameter file against the same list *before any node starts*,
so that a bad file (unknown key, wrong type, out of range) stops the launch with the file,
key and rule named. :func:`params_record` builds the record from the declared values, so a
node reads ``self.p.rate_hz`` and a misspelt name is an attribute error a type checker finds,
not a ``KeyError`` on the bench.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from rv_te_bench.errors import ParameterFileError
from rv_te_bench.safe_yaml import PARAMETER_FILE_LIMITS, brief, read_yaml_file

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping

_TYPES = ('bool', 'int', 'double', 'string', 'string_array', 'double_array')
#: The annotation of a record field -> the ROS parameter type.
_ANNOTATION_TYPES = {'bool': 'bool', 'int': 'int', 'float': 'double', 'str': 'string',
                     'tuple[str, ...]': 'string_array', 'tuple[float, ...]': 'double_array'}
_SPEC = 'rv_te_bench.param'
R = TypeVar('R')


@dataclass(frozen=True)
class ParamSpec:
    """One node parameter.

    Attributes:
        name: Parameter name (same as the config field it feeds).
        type: One of ``bool``, ``int``, ``double``, ``string``, ``string_array``,
            ``double_array``.
        default: Default value.
        description: What it is, with the unit in brackets, e.g. ``'Sample rate [Hz]'``.
        min_value: Inclusive lower bound for numbers (None: unbounded).
        max_value: Inclusive upper bound for numbers (None: unbounded).
        choices: Allowed values for strings (empty: any).
        read_only: True when a change needs a restart.
        deprecated_by: Name of the parameter that replaces this one ('' when current): the
            old spelling still works, and a parameter file that sets it gets a warning.
        rule: A further check of a value of the right type: None if fine, else the rule it
            breaks (one phrase), e.g. a folder name that must not leave its output folder.
    """

    name: str
    type: str
    default: Any
    description: str
    min_value: float | None = None
    max_value: float | None = None
    choices: tuple[str, ...] = ()
    read_only: bool = True
    deprecated_by: str = ''
    rule: Callable[[Any], str | None] | None = None

    def __post_init__(self) -> None:
        """Check the spec itself (a programming error if it fails)."""
        if self.type not in _TYPES:
            msg = f'ParamSpec {self.name!r}: type {self.type!r} not in {_TYPES}'
            raise ValueError(msg)
        problem = self.check(self.default)
        if problem:
            msg = f'ParamSpec {self.name!r}: default {problem}'
            raise ValueError(msg)

    def check(self, value: object) -> str | None:
        """Return None when ``value`` is acceptable, else the rule it breaks (one phrase)."""
        problem = self._check_type(value)
        if problem is None and self.rule is not None:
            problem = self.rule(value)
        return problem

    def _check_type(self, value: object) -> str | None:
        t = self.type
        if t == 'bool':
            return None if isinstance(value, bool) else f'must be a bool, got {brief(value)}'
        if t == 'int':
            if isinstance(value, bool) or not isinstance(value, int):
                return f'must be an integer, got {brief(value)}'
            return self._range(value)
        if t == 'double':
            if isinstance(value, bool) or not isinstance(value, int | float):
                return f'must be a number, got {brief(value)}'
            if not math.isfinite(value):
                return f'must be finite, got {brief(value)}'
            return self._range(float(value))
        if t == 'string':
            if isinstance(value, str) and not _is_utf8(value):
                return f'must be UTF-8 text, got {brief(value)} (undecodable bytes)'
            if not isinstance(value, str):
                return f'must be a string, got {brief(value)}'
            if self.choices and value not in self.choices:
                return f'must be one of {list(self.choices)}, got {brief(value)}'
            return None
        if t == 'string_array':
            if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
                return f'must be a list of strings, got {brief(value)}'
            if not all(_is_utf8(v) for v in value):
                return f'must hold UTF-8 text, got {brief(value)} (undecodable bytes)'
            return None
        if t == 'double_array':
            if not isinstance(value, list | tuple) or not all(
                    isinstance(v, int | float) and not isinstance(v, bool) for v in value):
                return f'must be a list of numbers, got {brief(value)}'
            if not all(math.isfinite(v) for v in value):
                return f'must hold finite numbers, got {brief(value)}'
            return None
        return None

    def _range(self, value: float) -> str | None:
        if self.min_value is not None and value < self.min_value:
            return f'must be >= {self.min_value:g}, got {brief(value)}'
        if self.max_value is not None and value > self.max_value:
            return f'must be <= {self.max_value:g}, got {brief(value)}'
        return None


def _is_utf8(text: str) -> bool:
    """False for a str holding surrogates (undecodable bytes of a command line or path)."""
    try:
        text.encode('utf-8')
    except UnicodeEncodeError:
        return False
    return True


def coerce_value(spec: ParamSpec, value: Any) -> Any:
    """The value in the declared type where that is lossless (an int for a double).

    ROS parameter files write ``300`` for 300.0; rclpy would reject the integer for a
    double parameter, so every path (files, ``--param``, single process) coerces here.
    """
    if spec.type == 'double' and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if spec.type == 'double_array' and isinstance(value, list | tuple):
        return [float(v) if isinstance(v, int) and not isinstance(v, bool) else v
                for v in value]
    return value


def coerce_parameters(specs: tuple[ParamSpec, ...], values: dict[str, Any]) -> dict[str, Any]:
    """:func:`coerce_value` for every known key of ``values``."""
    by_name = {s.name: s for s in specs}
    return {k: coerce_value(by_name[k], v) if k in by_name else v for k, v in values.items()}


def check_parameters(specs: tuple[ParamSpec, ...], values: dict[str, Any], *, where: str,
                     ) -> None:
    """Check ``values`` against ``specs``.

    Args:
        specs: The node's parameter list.
        values: Parameter name -> value (from a file or a command line).
        where: Where the values come from, for the message (file and node name).

    Raises:
        ParameterFileError: Unknown key, wrong type or out of range; names where, key, rule.
    """
    by_name = {s.name: s for s in specs}
    for key, value in values.items():
        if key in {'use_sim_time'}:
            if not isinstance(value, bool):
                msg = f'{where}: parameter {key!r} must be a bool, got {brief(value)}'
                raise ParameterFileError(msg)
            continue
        spec = by_name.get(key)
        if spec is None:
            msg = (f'{where}: unknown parameter {brief(key)}; known: '
                   f'{", ".join(sorted(by_name))}')
            raise ParameterFileError(msg)
        problem = spec.check(value)
        if problem:
            msg = f'{where}: parameter {key!r} {problem}'
            raise ParameterFileError(msg)
        if spec.deprecated_by:
            # FutureWarning: shown by default (users' parameter files, not developers' code)
            warnings.warn(f'{where}: parameter {key!r} is deprecated; use '
                          f'{spec.deprecated_by!r} ({spec.description})', FutureWarning,
                          stacklevel=2)


def load_parameter_file(path: str | Path) -> dict[str, dict[str, Any]]:
    """Read a ROS 2 parameter file: ``node_name: {ros__parameters: {...}}``.

    Node keys may carry a namespace (``/bench1/te_node``, or nested mappings
    ``bench1: {te_node: {ros__parameters: ...}}`` as rcl reads them) or be the wildcard
    ``/**``. Read as rcl reads it for the nodes (:mod:`rv_te_bench.safe_yaml`, ``'ros'``
    scalars: ``1.0e12`` is a double, ``yes`` a bool), within
    :data:`~rv_te_bench.safe_yaml.PARAMETER_FILE_LIMITS` and with no aliases (rcl refuses
    them); a key repeated in one mapping is an error (rcl would silently keep the last).

    Returns:
        Node key -> parameter dict (nested parameter names joined with ``.``).

    Raises:
        ParameterFileError: Missing file, not UTF-8/16 text, bad YAML, over a limit, a
            repeated key, or not the ROS 2 layout.
    """
    p = Path(path)
    data = read_yaml_file(p, what='parameter file', limits=PARAMETER_FILE_LIMITS,
                          scalars='ros', unique_keys=True)
    if data is None:
        return {}
    if not isinstance(data, dict):
        msg = f'parameter file {p}: top level must map node names to ros__parameters'
        raise ParameterFileError(msg)
    out: dict[str, dict[str, Any]] = {}
    _collect_nodes(data, '', p, out)
    return out


def _collect_nodes(mapping: dict[str, Any], prefix: str, p: Path,
                   out: dict[str, dict[str, Any]]) -> None:
    """Node keys (nested mappings are namespaces, as rcl joins them with '/')."""
    for key, body in mapping.items():
        name = f'{prefix}/{key}' if prefix else str(key)
        if key == 'ros__parameters':
            msg = f'parameter file {p}: "ros__parameters" needs a node name above it'
            raise ParameterFileError(msg)
        if isinstance(body, dict) and 'ros__parameters' in body:
            if set(body) != {'ros__parameters'} or not isinstance(body['ros__parameters'],
                                                                  dict):
                msg = (f'parameter file {p}: node {brief(name)} must contain exactly '
                       f'"ros__parameters: {{...}}"')
                raise ParameterFileError(msg)
            if name in out:
                msg = f'parameter file {p}: node {brief(name)} is given twice'
                raise ParameterFileError(msg)
            out[name] = _flatten_params(body['ros__parameters'])
        elif isinstance(body, dict) and body:
            _collect_nodes(body, name, p, out)
        else:
            msg = (f'parameter file {p}: node {brief(name)} must contain exactly '
                   f'"ros__parameters: {{...}}"')
            raise ParameterFileError(msg)


def _flatten_params(params: dict[str, Any], prefix: str = '') -> dict[str, Any]:
    """ROS 2 nests dotted parameter names as mappings; flatten them back."""
    out: dict[str, Any] = {}
    for k, v in params.items():
        key = f'{prefix}{k}'
        if isinstance(v, dict):
            out.update(_flatten_params(v, key + '.'))
        else:
            out[key] = v
    return out


def param(default: Any, description: str, *, min_value: float | None = None,
          max_value: float | None = None, choices: tuple[str, ...] = (), read_only: bool = True,
          deprecated_by: str = '', rule: Callable[[Any], str | None] | None = None) -> Any:
    """A node parameter as a field of its frozen record: the default and the descriptor.

    The field's annotation gives the type (``bool``, ``int``, ``float``, ``str``,
    ``tuple[str, ...]``, ``tuple[float, ...]``); the other arguments are those of
    :class:`ParamSpec`. A list default is kept as a tuple (the record is frozen).
    """
    if isinstance(default, list):
        default = tuple(default)
    return dataclasses.field(default=default, metadata={_SPEC: {
        'description': description, 'min_value': min_value, 'max_value': max_value,
        'choices': tuple(choices), 'read_only': read_only, 'deprecated_by': deprecated_by,
        'rule': rule}})


def param_specs(record: type) -> tuple[ParamSpec, ...]:
    """The :class:`ParamSpec` of every field of a node's parameter record, in field order.

    Raises:
        ValueError: A field is not made by :func:`param` or has an annotation that is no
            parameter type (a programming error).
    """
    out = []
    for f in dataclasses.fields(record):
        meta = f.metadata.get(_SPEC)
        kind = _ANNOTATION_TYPES.get(str(f.type))
        if meta is None or kind is None:
            msg = (f'{record.__name__}.{f.name}: a parameter record field needs param() and '
                   f'one of {sorted(_ANNOTATION_TYPES)}, got {f.type!r}')
            raise ValueError(msg)
        default = list(f.default) if isinstance(f.default, tuple) else f.default
        out.append(ParamSpec(f.name, kind, default, **meta))
    return tuple(out)


def params_record(record: type[R], values: Mapping[str, Any]) -> R:
    """A node's parameter record from declared (or merged) values.

    Fields not in ``values`` keep their defaults; names that are not fields (``use_sim_time``)
    are left out; arrays become tuples.
    """
    names = {f.name for f in dataclasses.fields(record)}  # type: ignore[arg-type]
    return record(**{k: tuple(v) if isinstance(v, list) else v
                     for k, v in values.items() if k in names})


def params_changed(record: R, values: Mapping[str, Any]) -> R:
    """``record`` with the parameters in ``values`` set (a runtime change the node accepted);
    names that are not fields are left out, arrays become tuples."""
    names = {f.name for f in dataclasses.fields(record)}  # type: ignore[arg-type]
    return dataclasses.replace(record, **{  # type: ignore[type-var]
        k: tuple(v) if isinstance(v, list) else v for k, v in values.items() if k in names})


def params_values(record: Any) -> dict[str, Any]:
    """The parameters of a record as plain values (arrays as lists), in field order: what
    a node declared, for a record of the session (YAML, JSON)."""
    return {f.name: list(v) if isinstance(v := getattr(record, f.name), tuple) else v
            for f in dataclasses.fields(record)}
