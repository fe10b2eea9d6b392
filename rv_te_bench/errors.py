"""Exceptions of rv_te_bench. Each subclass also derives from the matching builtin."""

from __future__ import annotations


class RvTeError(Exception):
    """Base class of every error raised by rv_te_bench."""


class TeInputError(RvTeError, ValueError):
    """Measurement data given to the TE core is malformed (shapes, non-finite, order)."""


class TeConfigError(RvTeError, ValueError):
    """A TE analysis setting is invalid."""


class CompensationError(RvTeError, ValueError):
    """A compensation or identification request cannot be honoured."""


class BenchDescriptionError(TeConfigError):
    """A bench description file is invalid (names the file, the key and the rule)."""


class DataImportError(RvTeError, ValueError):
    """A measurement file cannot be imported (names the file, column/channel and row/sample)."""


class BagError(RvTeError):
    """A bag cannot be read or written."""


class BenchInfoError(BagError):
    """The bag's messages are readable but its BenchInfo is damaged (the bag's ratio and
    crank order, or its preset, given on the command line still analyse it)."""


class BagExistsError(BagError, FileExistsError):
    """The bag folder to create exists already (nothing is overwritten)."""


class ParameterFileError(RvTeError, ValueError):
    """A ROS-style parameter file is invalid (names file, key and rule)."""


class SpcError(RvTeError, ValueError):
    """A control chart or capability cannot be computed from the values given."""


class MsaError(RvTeError, ValueError):
    """Bad data for a measurement-system study (names what and why)."""


class StoreError(RvTeError):
    """The results store cannot be opened, written or queried."""


class AcceptanceError(RvTeError, ValueError):
    """An acceptance test plan, tolerance profile or test request is invalid."""


class PlanError(AcceptanceError):
    """A test plan is invalid (names the file, the step, the key and the rule)."""


class ToleranceError(AcceptanceError):
    """A tolerance profile is invalid (names the file, the metric, the key and the rule)."""


class YamlInputError(ParameterFileError):
    """YAML input is unreadable, invalid or over a limit (size, depth, aliases, nodes)."""


class YamlLimitError(YamlInputError):
    """YAML input over a limit: too large, too deep, aliases, or too many expanded nodes."""


class HeadLayoutError(TeConfigError):
    """Read heads at angles that cannot be combined as asked (duplicate heads, or no weighting
    of them cancels the once-per-revolution error); names the angles and the rule."""


class EncoderCalibrationError(TeConfigError):
    """An encoder calibration is invalid, expired or for another scale (names the file, the
    key or the serial)."""
