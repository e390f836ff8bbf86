"""moments_ref: NumPy reference implementation and numerical test oracle of moment shadow mapping.

The stable API is re-exported here; see docs/api.md for the full table.
"""

from ._arrays import InputError
from .moments import BIAS_FLOAT32, BIAS_UNORM16, BiasPreset, bias_moments, hankel, power_moments
from .msm import canonical_representation, reduce_light_leaking, shadow_intensity

__version__ = "0.1.0"

__all__ = [
    "__version__",
    "InputError",
    "power_moments",
    "hankel",
    "bias_moments",
    "BiasPreset",
    "BIAS_FLOAT32",
    "BIAS_UNORM16",
    "shadow_intensity",
    "canonical_representation",
    "reduce_light_leaking",
]
