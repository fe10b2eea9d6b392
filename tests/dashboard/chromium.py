"""Debian's chromium driven by Selenium (chromium-driver), as the live page's tests, the
benchmark (benchmarks/bench_dashboard.py) and the README screenshot use it.

Chromium runs headless, without sandbox or GPU, with no background networking, component
updates, sync or first-run work (a closed network) and a fresh profile directory each time.
Selenium is given the driver's path, so it never tries to download one.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

CHROMIUM = '/usr/bin/chromium'
CHROMEDRIVER = '/usr/bin/chromedriver'
FLAGS = ('--headless', '--no-sandbox', '--disable-gpu', '--disable-background-networking',
         '--disable-component-update', '--disable-sync', '--no-first-run',
         '--disable-dev-shm-usage', '--window-size=1400,2200')


def missing_reason() -> str | None:
    """Why the browser tests cannot run here (None: they can)."""
    for path, pkg in ((CHROMIUM, 'chromium'), (CHROMEDRIVER, 'chromium-driver')):
        if not (os.path.exists(path) or shutil.which(os.path.basename(path))):
            return (f'{path} not found: install the Debian packages chromium and '
                    f'chromium-driver (make system-deps; .ci/run does) to run the live '
                    f'page\'s browser tests (missing: {pkg})')
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium missing: pip install 'rv-te-bench[test]'"
    return None


@contextmanager
def chromium(width: int = 1400, height: int = 2200) -> Iterator[Any]:
    """A headless Chromium WebDriver with a fresh profile (quit and removed afterwards)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    profile = tempfile.mkdtemp(prefix='rv-te-chromium-')
    opts = webdriver.ChromeOptions()
    opts.binary_location = shutil.which('chromium') or CHROMIUM
    for f in FLAGS:
        opts.add_argument(f)
    opts.add_argument(f'--window-size={width},{height}')
    opts.add_argument(f'--user-data-dir={profile}')
    service = Service(executable_path=shutil.which('chromedriver') or CHROMEDRIVER)
    driver = webdriver.Chrome(service=service, options=opts)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def wait_for(cond: Callable[[], Any], timeout_s: float, what: str, step_s: float = 0.1) -> Any:
    """Poll ``cond`` until it returns something true; AssertionError naming ``what``."""
    end = time.monotonic() + timeout_s
    last: Any = None
    while time.monotonic() < end:
        last = cond()
        if last:
            return last
        time.sleep(step_s)
    msg = f'timed out after {timeout_s:g} s waiting for {what} (last: {last!r})'
    raise AssertionError(msg)


def page_state(driver: Any) -> dict[str, Any]:
    """What the page drew and counted (window.rvte), as plain JSON."""
    return driver.execute_script(
        'const d = window.rvte; if (!d) return null;'
        'return {draws: d.draws, updates: d.updates, connected: d.connected,'
        ' status: d.S.status, verdict: d.verdict || null, dominant: d.dominant || null,'
        ' drawn: d.drawn, latency: d.latency.slice(-5000), rxLatency: d.rxLatency.slice(-5000),'
        ' drawWall: d.drawWall.slice(-5000), errors: d.errors.slice(),'
        ' windows: [...d.S.windows.values()].map('
        '   w => ({index: w.index, pp_rad: w.pp_rad}))};')


def text(driver: Any, element_id: str) -> str:
    """The text of an element of the page."""
    return driver.execute_script(f'return document.getElementById({element_id!r}).textContent;')
