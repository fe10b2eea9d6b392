"""Shared helpers of the package tests (also used by tests/launch): the Foxglove layout's
message paths and the constants of rv_te_bench_ros/setup.py."""

from __future__ import annotations

import ast
import json
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
LAYOUT = REPO / 'docs' / 'foxglove_te_session.json'
PKG_DIR = REPO / 'rv_te_bench_ros'


def load_layout() -> dict[str, Any]:
    return json.loads(LAYOUT.read_text(encoding='utf-8'))


def layout_paths() -> list[tuple[str, str]]:
    """(panel id, message path) of every path in the layout."""
    out = []
    for panel_id, cfg in load_layout()['configById'].items():
        for p in cfg.get('paths', []):
            out.append((panel_id, p['value']))
        if 'xAxisPath' in cfg:
            out.append((panel_id, cfg['xAxisPath']['value']))
        for key in ('topicPath', 'topicToRender'):
            if key in cfg:
                out.append((panel_id, cfg[key]))
    return out


def setup_py_value(name: str) -> object:
    """A module-level constant of rv_te_bench_ros/setup.py, read without running setup()."""
    tree = ast.parse((PKG_DIR / 'setup.py').read_text(encoding='utf-8'))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == name for t in node.targets):
            return ast.literal_eval(node.value)
    msg = f'{name} not in setup.py'
    raise AssertionError(msg)
