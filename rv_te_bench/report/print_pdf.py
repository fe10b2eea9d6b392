"""The unit report printed to PDF by Chromium (``--pdf`` of ``rv-te test`` and ``rv-te
unit-report``): the same page a lab prints from its browser (A4, the print styles of
:mod:`rv_te_bench.report.unit_doc`), archived beside report.html to sign.

Chromium runs headless with a fresh profile folder, no header or footer lines (the page
has its own report number), and ``--no-sandbox`` only when run as root (Chromium refuses to
start as root otherwise).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from rv_te_bench.errors import RvTeError

__all__ = ['CHROMIUM_NAMES', 'print_to_pdf']

#: The browser's names on the PATH, tried in this order (Debian's package is ``chromium``).
CHROMIUM_NAMES = ('chromium', 'chromium-browser', 'google-chrome')


def print_to_pdf(html: Path, pdf: Path, *, timeout_s: float = 120.0) -> Path:
    """Print ``html`` to ``pdf`` with headless Chromium; returns ``pdf``.

    Raises:
        RvTeError: No Chromium on the PATH, or it failed or wrote no PDF (the reason in one
            line).
    """
    exe = next((p for n in CHROMIUM_NAMES if (p := shutil.which(n))), None)
    if exe is None:
        msg = (f'no Chromium to print {pdf.name} (looked for {", ".join(CHROMIUM_NAMES)} on '
               'the PATH; Debian: apt-get install chromium)')
        raise RvTeError(msg)
    pdf = pdf.resolve()
    pdf.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory(prefix='rv-te-print-') as profile:
        cmd = [exe, '--headless', '--disable-gpu', '--disable-dev-shm-usage',
               '--disable-background-networking', '--disable-component-update',
               '--no-first-run', f'--user-data-dir={profile}', '--no-pdf-header-footer',
               f'--print-to-pdf={pdf}', html.resolve().as_uri()]
        if hasattr(os, 'geteuid') and os.geteuid() == 0:
            cmd.insert(1, '--no-sandbox')
        try:
            done = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s,
                                  check=False)
        except subprocess.TimeoutExpired:
            msg = f'Chromium did not print {pdf.name} within {timeout_s:g} s'
            raise RvTeError(msg) from None
    if not pdf.exists() or pdf.stat().st_size == 0:
        last = (done.stderr.strip().splitlines() or ['no message'])[-1][:200]
        msg = f'Chromium (exit {done.returncode}) wrote no {pdf.name}: {last}'
        raise RvTeError(msg)
    return pdf
