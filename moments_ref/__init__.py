"""moments_ref: NumPy reference implementation and numerical test oracle of moment shadow mapping.

The stable core API (moments, Algorithm 1, affine and non-linear quantization,
texel packing) is re-exported here; docs/api.md lists every module's public
names and docs/architecture.md shows the layers the modules sit in.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from . import _shim
from ._arrays import InputError
from .affine import decode_unorm16, encode_unorm16, from_optimized, to_optimized
from .moments import BIAS_FLOAT32, BIAS_UNORM16, BiasPreset, bias_moments, hankel, power_moments
from .msm import canonical_representation, reduce_light_leaking, shadow_intensity
from .nonlinear import phi, phi_inverse, psi4, psi4_inverse, shade
from .packing import pack32, pack64, unpack32, unpack64

__version__ = "0.1.0"

# The old paths of moved modules (moments_ref.filtering, ...): one import hook reading _shim.MOVED.
_shim.install()


def __getattr__(name):
    """``moments_ref.<old path>`` of a moved module: the module at its new path (warns once)."""
    return _shim.old_attribute(name)

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
    "to_optimized",
    "from_optimized",
    "encode_unorm16",
    "decode_unorm16",
    "phi",
    "phi_inverse",
    "psi4",
    "psi4_inverse",
    "shade",
    "pack64",
    "unpack64",
    "pack32",
    "unpack32",
]
