"""The shared "finite positive number" check (its message names the quantity and the value).

The rule itself is :func:`sim._checks.real_number` (``sim`` may not import the package).
"""

from __future__ import annotations

from sim._checks import real_number

__all__ = ['finite_positive']


def finite_positive(value: float, name: str, error: type[Exception]) -> float:
    """``value`` as a float when it is finite and > 0, else ``error`` naming it.

    Args:
        value: The number to check (anything ``float()`` takes; its ``ValueError`` or
            ``TypeError`` is left to the caller).
        name: What it is, for the message (``''``: the message starts at "must").
        error: The exception class to raise (the caller's domain error).

    Raises:
        error: ``'<name> must be finite and > 0, got <value!r>'``.

    Examples:
        >>> finite_positive(79, 'gear_ratio', ValueError)
        79.0
        >>> finite_positive(0.0, 'gear_ratio', ValueError)
        Traceback (most recent call last):
        ...
        ValueError: gear_ratio must be finite and > 0, got 0.0
    """
    float(value)   # its ValueError / TypeError goes to the caller
    return real_number(name, value, '>0', error=error, coerce=True)
