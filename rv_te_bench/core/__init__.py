"""Measurement-side maths: Wang 2020 Eq. 22, streaming windows, statistics, order spectra,
compensation.

Pure numpy/scipy (and ``sim``); never imports rclpy.
"""

from __future__ import annotations
