"""``import plane_validation.scenes``: the synthetic scenes of :mod:`plane_validation.core.scenes`."""
import sys

from .core import scenes

sys.modules[__name__] = scenes
