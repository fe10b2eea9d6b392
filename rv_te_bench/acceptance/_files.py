"""Reading plan and tolerance files: a path (or one relative to a plan), or a shipped name."""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rv_te_bench.errors import YamlInputError
from rv_te_bench.safe_yaml import DOCUMENT_LIMITS, load_yaml

if TYPE_CHECKING:
    from collections.abc import Iterable

_MAX_TEXT = DOCUMENT_LIMITS.max_bytes
_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_.\-]{0,63}')


def shown_keys(keys: Iterable[object]) -> str:
    """Unknown keys for a message: the ones that look like names (a file of another kind,
    e.g. ``/etc/shadow`` given as a tolerance, must not have its lines printed); the rest
    only counted."""
    names = sorted(str(k) for k in keys if isinstance(k, str) and _NAME.fullmatch(k))
    other = sum(1 for k in keys if not (isinstance(k, str) and _NAME.fullmatch(k)))
    return str(names) + (f' and {other} more that are not names' if other else '')


def parse_yaml_text(text: str, origin: str, error: type[Exception]) -> Any:
    """A plan or tolerance file through the suite's bounded loader (size, depth, aliases,
    expanded nodes: :mod:`rv_te_bench.safe_yaml`), errors on one line as ``error``."""
    try:
        return load_yaml(text, origin=origin, limits=DOCUMENT_LIMITS, scalars='document')
    except YamlInputError as exc:
        raise error(str(exc)) from None


def shipped(folder: str) -> list[str]:
    """Names of the YAML files shipped in ``rv_te_bench/acceptance/<folder>``."""
    root = resources.files('rv_te_bench.acceptance').joinpath(folder)
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith('.yaml'))


def read_source(name_or_path: str | Path, *, folder: str, what: str, error: type[Exception],
                relative_to: Path | None = None) -> tuple[str, str]:
    """(text, origin) of a file, a file relative to ``relative_to``, or a shipped name.

    Raises:
        error: Unreadable file, or neither a file nor a shipped name (the shipped ones listed).
    """
    cands = [Path(name_or_path)]
    if relative_to is not None and not Path(name_or_path).is_absolute():
        cands.append(relative_to / name_or_path)
    for path in cands:
        if path.is_file():
            try:
                if path.stat().st_size > _MAX_TEXT:
                    msg = f'{what} {path} is larger than {_MAX_TEXT >> 20} MiB: not read'
                    raise error(msg)
                return path.read_text(encoding='utf-8'), str(path)
            except (OSError, UnicodeDecodeError) as exc:
                msg = f'{what} {path}: cannot read ({exc})'
                raise error(msg) from None
    name = str(name_or_path)
    if name not in shipped(folder):
        msg = (f'{what} {name!r}: no such file, and not a shipped {what} '
               f'({", ".join(shipped(folder))})')
        raise error(msg)
    text = resources.files('rv_te_bench.acceptance').joinpath(folder, f'{name}.yaml')
    return text.read_text('utf-8'), f'{what} {name}'
