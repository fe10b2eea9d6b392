"""Reducer presets: TOML data files shipped in ``sim/preset_data/``, a unit and a source per value.

File format (one file per preset, ``sim/preset_data/<name>.toml``)::

    name = "wang2020-2kv"
    model = "wang2020-2kv"          # which model consumes it (see MODEL_KINDS)
    description = "..."

    [gear]                          # sections group keys; the flat key is "gear.z_sun"
    z_sun = { value = 12, unit = "1", source = "Wang 2020 Table 1" }
    r_p_m = { value = 0.06108, unit = "m", source = "DESIGN.md s.4: 65 mm * cos 20 deg",
              note = "assumption ..." }

A value is either a table ``{value, unit, source[, note]}`` or a bare value (then unit and
source are empty; use that only for strings and flags). Values are SI (m, rad, s, N, kg);
angles in degrees are allowed only where the key ends in ``_deg``.

Overrides use the flat dotted key: ``--set gear.z_sun=13`` on the CLI or the parameter
``overrides: ["gear.z_sun=13"]`` on a node. The override keeps the type of the preset value
(int stays int, float stays float, list stays list); an unknown key or a value of the wrong
type raises :class:`sim.errors.PresetError` naming the key.

Models turn a :class:`Preset` into their frozen, validated parameter dataclasses; the rules
(positive teeth, ring teeth > planet teeth, finite values ...) live in those dataclasses and
name the key in their message.
"""

from __future__ import annotations

import functools
import math
import os
import stat
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from sim.errors import PresetError

_PRESET_DIR = 'preset_data'


@dataclass(frozen=True)
class PresetValue:
    """One preset value with its unit and where it comes from."""

    value: Any
    unit: str = ''
    source: str = ''
    note: str = ''


@dataclass(frozen=True)
class Preset:
    """A named, flat, read-only mapping ``dotted.key -> PresetValue``."""

    name: str
    model: str
    description: str
    values: dict[str, PresetValue] = field(repr=False)

    def __getitem__(self, key: str) -> Any:
        """Return the plain value of ``key``.

        Raises:
            PresetError: ``key`` is not in the preset.
        """
        try:
            return self.values[key].value
        except KeyError:
            msg = f'preset {self.name!r} has no key {key!r}'
            raise PresetError(msg) from None

    def get(self, key: str, default: Any = None) -> Any:
        """Return the plain value of ``key`` or ``default``."""
        pv = self.values.get(key)
        return default if pv is None else pv.value

    def keys(self) -> list[str]:
        """All flat keys, sorted."""
        return sorted(self.values)

    def section(self, prefix: str) -> dict[str, Any]:
        """Plain values of every key under ``prefix.`` with the prefix removed."""
        p = prefix + '.'
        return {k[len(p):]: v.value for k, v in self.values.items() if k.startswith(p)}

    def with_overrides(self, overrides: dict[str, str] | list[str] | None) -> Preset:
        """Return a copy with ``key=value`` overrides applied (types kept, keys checked).

        Args:
            overrides: A mapping ``key -> text`` or a list of ``"key=value"`` strings.

        Raises:
            PresetError: Unknown key, malformed item, or a value of the wrong type.
        """
        if not overrides:
            return self
        items = parse_override_items(overrides)
        new = dict(self.values)
        for key, text in items.items():
            if key not in new:
                close = [k for k in new if k.split('.')[-1] == key.split('.')[-1]]
                hint = f'; did you mean {close[0]!r}?' if close else ''
                msg = f'preset {self.name!r} has no key {key!r}{hint}'
                raise PresetError(msg)
            old = new[key]
            new[key] = PresetValue(
                _coerce(key, text, old.value), old.unit, 'override', f'was {old.value!r}')
        return Preset(self.name, self.model, self.description, new)

    def to_plain(self) -> dict[str, Any]:
        """``{key: value}`` for reports and metadata (JSON/YAML friendly)."""
        return {k: self.values[k].value for k in self.keys()}

    def describe_rows(self) -> list[dict[str, Any]]:
        """Rows ``{key, value, unit, source, note}`` for ``rv-te presets``."""
        return [
            {'key': k, 'value': v.value, 'unit': v.unit, 'source': v.source, 'note': v.note}
            for k, v in sorted(self.values.items())
        ]


def parse_override_items(overrides: dict[str, str] | list[str]) -> dict[str, str]:
    """Normalise overrides to ``{key: text}``.

    Raises:
        PresetError: An item is not of the form ``key=value``.
    """
    if isinstance(overrides, dict):
        return {str(k).strip(): str(v).strip() for k, v in overrides.items()}
    out: dict[str, str] = {}
    for item in overrides:
        if '=' not in item or not item.split('=', 1)[0].strip():
            msg = f'override {item!r} is not of the form key=value'
            raise PresetError(msg)
        key, text = item.split('=', 1)
        out[key.strip()] = text.strip()
    return out


def _coerce(key: str, text: str, like: object) -> object:
    """Parse ``text`` into the type of ``like``; name the key on failure."""
    try:
        if isinstance(like, bool):
            low = text.lower()
            if low in {'true', '1', 'yes'}:
                return True
            if low in {'false', '0', 'no'}:
                return False
            raise ValueError(text)
        if isinstance(like, int):
            return int(text)
        if isinstance(like, float):
            value = float(text)
            if not math.isfinite(value):
                msg = f'override {key}={text!r}: value must be finite'
                raise PresetError(msg)
            return value
        if isinstance(like, list):
            parts = [p for p in text.strip('[]').split(',') if p.strip()]
            elem = like[0] if like else 0.0
            return [_coerce(key, p.strip(), elem) for p in parts]
        if isinstance(like, str):
            return text
    except PresetError:
        raise
    except ValueError:
        msg = f'override {key}={text!r}: expected {type(like).__name__}'
        raise PresetError(msg) from None
    msg = f'override {key}: cannot override a value of type {type(like).__name__}'
    raise PresetError(msg)


def _flatten(prefix: str, table: dict[str, Any], out: dict[str, PresetValue]) -> None:
    for key, item in table.items():
        flat = f'{prefix}.{key}' if prefix else key
        if isinstance(item, dict) and 'value' in item:
            unknown = set(item) - {'value', 'unit', 'source', 'note'}
            if unknown:
                msg = f'preset key {flat!r}: unknown fields {sorted(unknown)}'
                raise PresetError(msg)
            out[flat] = PresetValue(
                item['value'], item.get('unit', ''), item.get('source', ''), item.get('note', ''))
        elif isinstance(item, dict):
            _flatten(flat, item, out)
        else:
            out[flat] = PresetValue(item)


#: Largest preset file read [bytes] (the shipped ones are ~10 kB).
MAX_PRESET_BYTES = 1 << 20


def _read_preset_file(path: Path) -> str:
    """A preset TOML file's text: a regular file, at most MAX_PRESET_BYTES, UTF-8."""
    try:
        # O_NONBLOCK: a FIFO would otherwise block the open itself, before the check
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, 'O_NOCTTY', 0))
        with os.fdopen(fd, 'rb') as f:
            if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
                msg = f'preset {path}: not a regular file'
                raise PresetError(msg)
            data = f.read(MAX_PRESET_BYTES + 1)
    except OSError as exc:
        msg = f'preset {path}: cannot read ({exc.strerror or exc})'
        raise PresetError(msg) from None
    if len(data) > MAX_PRESET_BYTES:
        msg = f'preset {path} is larger than {MAX_PRESET_BYTES >> 20} MiB: not read'
        raise PresetError(msg)
    try:
        return data.decode('utf-8')
    except UnicodeDecodeError as exc:
        msg = (f'preset {path} is not UTF-8 text (byte 0x{data[exc.start]:02x} at offset '
               f'{exc.start}); TOML files are UTF-8')
        raise PresetError(msg) from None


def preset_from_text(text: str, origin: str = '<text>') -> Preset:
    """Parse a preset from TOML text.

    Raises:
        PresetError: Not valid TOML, or ``name``/``model`` missing.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = f'preset {origin}: not valid TOML ({exc})'
        raise PresetError(msg) from None
    except RecursionError:
        msg = f'preset {origin}: not valid TOML (nested too deeply)'
        raise PresetError(msg) from None
    name = data.pop('name', None)
    model = data.pop('model', None)
    description = data.pop('description', '')
    if not isinstance(name, str) or not isinstance(model, str):
        msg = f'preset {origin}: top-level "name" and "model" strings are required'
        raise PresetError(msg)
    values: dict[str, PresetValue] = {}
    _flatten('', data, values)
    return Preset(name, model, description, values)


def available_presets() -> list[str]:
    """Names of the presets shipped in the package, sorted."""
    root = resources.files('sim').joinpath(_PRESET_DIR)
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith('.toml'))


def load_preset(name_or_path: str | Path, overrides: dict[str, str] | list[str] | None = None,
                ) -> Preset:
    """Load a shipped preset by name (or a TOML file by path) and apply overrides.

    Raises:
        PresetError: Unknown preset (the message lists the known ones), bad file, bad override.
    """
    path = Path(name_or_path)
    if path.suffix == '.toml' and path.exists():
        preset = preset_from_text(_read_preset_file(path), str(path))
    else:
        name = str(name_or_path)
        known = available_presets()
        if name not in known:
            msg = f'unknown preset {name!r}; known presets: {", ".join(known)}'
            raise PresetError(msg)
        shipped = _shipped_preset(name)   # parsed once per process (a copy handed out)
        preset = Preset(shipped.name, shipped.model, shipped.description, dict(shipped.values))
    return preset.with_overrides(overrides)


@functools.cache
def _shipped_preset(name: str) -> Preset:
    """A preset shipped in the package, parsed (a bench description, its BenchInfo and the
    simulator each load it: one TOML parse, not three, per ``rv-te import``, issue 41)."""
    text = resources.files('sim').joinpath(_PRESET_DIR, f'{name}.toml').read_text('utf-8')
    return preset_from_text(text, name)
