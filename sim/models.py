"""The TE-model interface the bench uses, and the registry from ``preset.model`` to a factory.

Factories are named as ``'module:function'`` strings and imported lazily so that loading a
2K-V preset does not import the RV models (and vice versa).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Protocol

from sim.errors import PresetError

if TYPE_CHECKING:
    from collections.abc import Callable

    import numpy as np

    from sim.kinematics import ReducerKinematics
    from sim.presets import Preset


class TeModel(Protocol):
    """A reducer model that turns input motion and load into transmission error.

    ``te_rad`` takes one block of consecutive samples and returns
    TE = theta_out - theta_in / i [rad] at those samples. Consecutive calls continue one run.
    """

    kinematics: ReducerKinematics

    def te_rad(self, t_s: np.ndarray, theta_in_rad: np.ndarray, omega_in_rad_s: np.ndarray,
               load_nm: np.ndarray) -> np.ndarray:
        """TE at the given samples [rad]; advances the model state."""
        ...

    def reset(self) -> None:
        """Return to the initial state."""
        ...


# preset.model -> 'module:factory'; factory(preset, mode) -> TeModel
MODEL_FACTORIES: dict[str, str] = {
    'wang2020-2kv': 'sim.wang2020:build_te_model',
    'hu2020-rv': 'sim.hu2020:build_te_model',
    'li2023-rv': 'sim.li2023:build_te_model',
}


def build_te_model(preset: Preset, mode: str) -> TeModel:
    """Build the TE model a preset describes.

    Args:
        preset: A loaded preset (overrides applied).
        mode: Model mode, e.g. ``'nlte'``, ``'ste'`` or ``'dte'`` (which ones a model
            supports is the model's business; an unsupported mode raises).

    Raises:
        PresetError: The preset names a model that is not registered.
    """
    target = MODEL_FACTORIES.get(preset.model)
    if target is None:
        msg = (f'preset {preset.name!r}: unknown model {preset.model!r}; '
               f'known models: {", ".join(sorted(MODEL_FACTORIES))}')
        raise PresetError(msg)
    module_name, func_name = target.split(':')
    factory: Callable[[Preset, str], TeModel] = getattr(importlib.import_module(module_name),
                                                       func_name)
    return factory(preset, mode)
