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
    exec(compile(text, module.__file__, 'exec'), module.__dict__)  # noqa: S102
    return module
