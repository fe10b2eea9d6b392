"""Which bags a list of folders, files and glob patterns names."""

from __future__ import annotations

import glob
import os
from pathlib import Path

from rv_te_bench.errors import BagError

__all__ = ['discover_bags']

_GLOB_CHARS = frozenset('*?[')


def _is_bag_folder(p: Path) -> bool:
    return (p / 'metadata.yaml').is_file()


def _walk(root: Path) -> list[Path]:
    """Bag folders (metadata.yaml) and lone .mcap files below ``root``, not inside bags."""
    found: list[Path] = []
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        here = Path(dirpath)
        if 'metadata.yaml' in filenames:
            found.append(here)
            dirnames.clear()          # a bag's files are the bag's
            continue
        found.extend(here / f for f in filenames if f.endswith('.mcap'))
        dirnames.sort()
    return found


def discover_bags(specs: list[str]) -> list[Path]:
    """Resolve BAG arguments: bag folders, .mcap files, folders to search, glob patterns.

    A folder that is not a bag is searched recursively (bags inside are not descended).
    Patterns use ``glob`` with ``**`` (quote them so that the shell leaves them alone).

    Raises:
        BagError: A path that does not exist, or a pattern/folder that names no bag.
    """
    out: dict[Path, None] = {}
    for spec in specs:
        if _GLOB_CHARS & set(spec):
            hits = [Path(h) for h in sorted(glob.glob(spec, recursive=True))]
            bags = [h for h in hits if _is_bag_folder(h)
                    or (h.is_file() and h.suffix == '.mcap' and not _is_bag_folder(h.parent))]
            bags += [b for h in hits if h.is_dir() and not _is_bag_folder(h) for b in _walk(h)]
            if not bags:
                msg = f'pattern {spec[:200]!r} names no bag (folder with metadata.yaml or .mcap)'
                raise BagError(msg)
        else:
            p = Path(spec)
            if not p.exists():
                msg = f'{spec[:200]}: no such file or folder'
                raise BagError(msg)
            bags = [p] if _is_bag_folder(p) or p.is_file() else _walk(p)
            if not bags:
                msg = f'{spec[:200]}: no bag below this folder (folder with metadata.yaml or .mcap)'
                raise BagError(msg)
        for b in bags:
            out[b.resolve()] = None
    return list(out)
