"""Kernel conformance: a compute shader, as shipped, on the kernel golden cases on both drivers.

``moments-ref conformance --kernel (--glsl | --hlsl | --wgsl) FILE --entry NAME --case CASE``
compiles the kernel, reads what it declares (:mod:`.reflect`), matches its bindings
to the case's contract (:mod:`.contract`, :mod:`.bind`), fills the inputs (a
multisampled depth texture or buffers, the uniform block), dispatches the grid the
case implies in the driver process under the watchdog (:mod:`.._supervisor`), reads the output
back and judges it texel by texel with the one comparator (:mod:`.verdict`). The
shipped kernels: :mod:`.shipped`.
"""

from .bind import BindingError, match
from .contract import BLOCK, MAX_VIEWS, PARAMS, PARAMS_BYTES, THREADS, Contract, contract, dispatches, params_block
from .reflect import Interface, Resource, from_spirv, from_wgsl
from .run import KERNEL_DRIVERS, KernelReport, numpy_times, prepare, run_kernel

__all__ = ["run_kernel", "KernelReport", "KERNEL_DRIVERS", "BindingError", "match", "contract", "Contract",
           "dispatches", "params_block", "PARAMS", "PARAMS_BYTES", "MAX_VIEWS", "BLOCK", "THREADS", "Interface",
           "Resource", "from_spirv", "from_wgsl", "prepare", "numpy_times"]
