"""Encoder calibration files (YAML): read bounded, written atomically.

The record and its file form are :mod:`rv_te_bench.core.encoder_calibration`; this module
only moves it to and from disk.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from rv_te_bench.core.encoder_calibration import EncoderCalibration, calibration_from_plain
from rv_te_bench.errors import EncoderCalibrationError, YamlInputError
from rv_te_bench.io.files import write_atomic
from rv_te_bench.safe_yaml import DOCUMENT_LIMITS, read_yaml_file

__all__ = ['load_encoder_calibration', 'write_encoder_calibration']


def load_encoder_calibration(path: str | Path) -> EncoderCalibration:
    """Read and validate a calibration file.

    Raises:
        EncoderCalibrationError: Unreadable, not YAML, over the limits, or a bad key (one
            line naming the file and the key).
    """
    p = Path(path)
    try:
        data = read_yaml_file(p, what='encoder calibration', limits=DOCUMENT_LIMITS)
    except YamlInputError as exc:
        raise EncoderCalibrationError(str(exc)) from None
    if data is None:
        msg = f'encoder calibration {p}: the file is empty'
        raise EncoderCalibrationError(msg)
    return calibration_from_plain(data, f'encoder calibration {p}')


def write_encoder_calibration(path: str | Path, calibration: EncoderCalibration, *,
                              overwrite: bool = False) -> Path:
    """Write ``calibration`` to ``path`` (atomically: whole or not at all).

    Raises:
        FileExistsError: The file exists and ``overwrite`` is False.
    """
    p = Path(path)
    if p.exists() and not overwrite:
        msg = f'Output path {p} exists already'
        raise FileExistsError(msg)
    header = ('# Encoder calibration (rv-te). The scale error e(u) = sum a sin(k u + phi) in\n'
              '# the scale coordinate u = reading - scale index - head angle; u_arcsec is the\n'
              '# standard uncertainty of each harmonic. Orders listed as undetermined stay\n'
              '# in the readings it corrects.\n')
    write_atomic(p, header + yaml.safe_dump(calibration.to_plain(), sort_keys=False))
    return p
