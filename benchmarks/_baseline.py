"""Load a module as it was at another git revision, for side-by-side benchmarks.

``load_at(rev, 'sim/wang2020.py', 'sim.wang2020')`` compiles the file's text at ``rev`` into a
fresh module (its imports resolve against the current tree), so the old and the new code run
in one process on one machine state: the ratios the benchmark READMEs report.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]


def load_at(rev: str, path: str, name: str) -> ModuleType:
    """The module ``name`` from ``path`` as of git revision ``rev`` (registered as
    ``name + '_at_' + rev``, so that dataclasses and pickling find it)."""
    text = subprocess.run(['git', '-C', str(ROOT), 'show', f'{rev}:{path}'], check=True,
                          capture_output=True, text=True).stdout
    mod_name = f'{name}_at_{rev}'.replace('-', '_').replace('.', '_').replace('~', '_')
    spec = importlib.util.spec_from_loader(mod_name, loader=None)
    assert spec is not None
    module = importlib.util.module_from_spec(spec)
    module.__file__ = f'{path}@{rev}'
    sys.modules[mod_name] = module
    exec(compile(text, module.__file__, 'exec'), module.__dict__)
    return module


# the TE core as one unit (with the order set the spectra read their lines from, since
# issue 41 caches them): stream imports spectrum and te (and, since issue 39, its record
# types) at import time, so an old stream must see the old spectrum and te (its own
# revision), not the current ones; a file a revision does not have is skipped
CORE_MODULES = (('rv_te_bench/core/orders.py', 'rv_te_bench.core.orders'),   # (its lines)
                ('rv_te_bench/core/te.py', 'rv_te_bench.core.te'),
                ('rv_te_bench/core/spectrum.py', 'rv_te_bench.core.spectrum'),
                ('rv_te_bench/core/stream_records.py', 'rv_te_bench.core.stream_records'),
                ('rv_te_bench/core/stream.py', 'rv_te_bench.core.stream'),
                ('rv_te_bench/core/offline.py', 'rv_te_bench.core.offline'))


def _exists_at(rev: str, path: str) -> bool:
    return subprocess.run(['git', '-C', str(ROOT), 'cat-file', '-e', f'{rev}:{path}'],
                          check=False, capture_output=True).returncode == 0


def load_core_at(rev: str) -> dict[str, ModuleType]:
    """The TE core modules (orders, te, spectrum, stream records, stream, offline) as of
    ``rev``,
    keyed by module name.

    Each is compiled while the ones loaded before it stand in for their current versions in
    ``sys.modules``, so the old stream uses the old spectrum and te. Use :func:`swapped`
    to run code that imports them by name (e.g. ``analyze_bag``) against the old ones.
    Before issue 39 split it, ``stream`` held the record types and ``analyze_blocks``: at
    such a revision it stands in for ``stream_records`` and ``offline`` too.
    """
    loaded: dict[str, ModuleType] = {}
    for path, name in CORE_MODULES:
        if not _exists_at(rev, path):
            continue
        with swapped(loaded):
            loaded[name] = load_at(rev, path, name)
    for name in ('rv_te_bench.core.stream_records', 'rv_te_bench.core.offline'):
        loaded.setdefault(name, loaded['rv_te_bench.core.stream'])
    return loaded


# the bag reader as one unit (issue 41 round 4 changed the record walk and the opener): each
# module as of REV, loaded after the ones it imports, so the old reader runs on its own
# walk, storage and opener; the readers of BenchInfo and the session's head record too
IO_MODULES = (('rv_te_bench/io/_bag_types.py', 'rv_te_bench.io._bag_types'),
              ('rv_te_bench/io/_mcap_scan.py', 'rv_te_bench.io._mcap_scan'),
              ('rv_te_bench/io/_storage_mcap.py', 'rv_te_bench.io._storage_mcap'),
              ('rv_te_bench/io/_storage_sqlite3.py', 'rv_te_bench.io._storage_sqlite3'),
              ('rv_te_bench/io/_bag_open.py', 'rv_te_bench.io._bag_open'),
              ('rv_te_bench/io/_encoder_cdr.py', 'rv_te_bench.io._encoder_cdr'),
              ('rv_te_bench/io/bench_record.py', 'rv_te_bench.io.bench_record'),
              ('rv_te_bench/io/session_heads.py', 'rv_te_bench.io.session_heads'),
              ('rv_te_bench/io/bag_reader.py', 'rv_te_bench.io.bag_reader'))


def load_io_at(rev: str) -> dict[str, ModuleType]:
    """The bag reader's modules (:data:`IO_MODULES`) as of ``rev``, keyed by module name,
    each compiled while the ones before it stand in for their current versions (use with
    :func:`swapped`, beside :func:`load_core_at`'s)."""
    loaded: dict[str, ModuleType] = {}
    for path, name in IO_MODULES:
        if _exists_at(rev, path):
            with swapped(loaded):
                loaded[name] = load_at(rev, path, name)
    return loaded


class swapped:  # noqa: N801 - used like a function: with swapped(mods): ...
    """Context: ``sys.modules`` entries (and the parent packages' attributes) replaced by
    ``modules`` ({name: module}), restored on exit."""

    def __init__(self, modules: dict[str, ModuleType]) -> None:
        self._modules = modules
        self._saved: dict[str, tuple[ModuleType | None, ModuleType | None]] = {}

    def __enter__(self) -> None:
        import importlib

        for name, mod in self._modules.items():
            parent_name, _, attr = name.rpartition('.')
            parent = importlib.import_module(parent_name)
            self._saved[name] = (sys.modules.get(name), getattr(parent, attr, None))
            sys.modules[name] = mod
            setattr(parent, attr, mod)

    def __exit__(self, *exc: object) -> None:
        for name, (mod, attr_mod) in self._saved.items():
            parent_name, _, attr = name.rpartition('.')
            if mod is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = mod
            if attr_mod is not None:
                setattr(sys.modules[parent_name], attr, attr_mod)
            elif getattr(sys.modules[parent_name], attr, None) is not None:
                # not imported before: the package must not keep the old one as its attribute
                # (``from package import module`` would then find it)
                delattr(sys.modules[parent_name], attr)
        self._saved.clear()
