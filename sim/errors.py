"""Exceptions of the sim package."""

from __future__ import annotations


class SimError(Exception):
    """Base class of every error raised by ``sim``."""


class PresetError(SimError, ValueError):
    """A preset or one of its values is invalid; the message names the key and the rule."""


class ModelInputError(SimError, ValueError):
    """An argument of a model function is invalid (shape, range, non-finite)."""
