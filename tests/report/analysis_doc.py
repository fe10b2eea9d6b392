"""The analysis JSON of a bag as text, without what differs between two runs of the same
analysis (when it ran, how long it took): for bit-for-bit comparisons of two paths."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

from rv_te_bench.report.analysis import analyze_bag
from rv_te_bench.report.html import report_json

if TYPE_CHECKING:
    from pathlib import Path


def analysis_doc(bag: Path) -> str:
    """``rv-te analyze``'s JSON of ``bag``, keys sorted, ``generated_utc`` and each bag's
    ``elapsed_s`` left out."""
    doc = report_json([analyze_bag(bag)])
    doc.pop('generated_utc', None)
    for b in doc['bags']:
        b.pop('elapsed_s', None)
    return json.dumps(doc, sort_keys=True)
