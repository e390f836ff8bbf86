"""``--adapter cpu``: a Slang function on the CPU, through Slang's ``cpp`` target and the system C++ compiler.

An optional third driver for Slang ports (the package stays pure Python: the C++ is
compiled at run time by the user's compiler, ``$CXX`` or ``g++``/``c++``/``clang++``).
The harness's wrapper (:func:`._wrap.wrap_slang`) goes to C++ (``-target cpp``), which
is compiled with ``-O2 -ffp-contract=off`` (every operation rounded as written, no
fused multiply-add: what ``precise`` asks of a GPU; Slang writes ``precise`` into the
C++, where ``-Dprecise=`` removes it) into a shared library. Slang's C++
compute ABI is ``mr_main(ComputeVaryingInput*, entryPointParams, globalParams)``; the
global parameters are the wrapper's structured buffers in declaration order, each a
``{pointer, count}`` pair, so the library is called through ``ctypes`` in a child
process (a port that crashes or loops takes down the child, not the harness; the
watchdog bounds it).

Functions only: Slang's ``cpp`` target refuses ``GroupMemoryBarrierWithGroupSync`` (error
E36107, "unavailable features in entry point"), so no kernel of HPG17 §4.1 runs here.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

__all__ = ["compiler", "not_available", "KERNEL_REFUSAL", "run_cpu"]

#: Why kernels cannot take ``--adapter cpu`` (measured with slangpy's compiler library).
KERNEL_REFUSAL = ("adapter cpu: Slang's cpp target refuses GroupMemoryBarrierWithGroupSync (error E36107), which "
                  "every HPG17 §4.1 kernel needs; run kernels on gl or vulkan")
# Slang's cpp target writes HLSL's ``precise`` qualifier into the C++ (no C++ keyword): defined away, since
# -ffp-contract=off already rounds every operation as written.
_FLAGS = ("-O2", "-ffp-contract=off", "-fno-fast-math", "-Dprecise=", "-shared", "-fPIC")
_BUILT = {}


def compiler():
    """The C++ compiler (``$CXX``, else ``g++``, ``c++`` or ``clang++`` on PATH), or None."""
    cands = [os.environ["CXX"]] if os.environ.get("CXX") else ["g++", "c++", "clang++"]
    return next((shutil.which(c) for c in cands if shutil.which(c)), None)


def not_available():
    """Why ``--adapter cpu`` cannot run here, or None."""
    from . import _slang

    if not _slang.available():
        return "adapter cpu: needs the Slang extra (pip install -e \".[slang]\")"
    if compiler() is None:
        return "adapter cpu: needs a C++ compiler ($CXX, g++, c++ or clang++ on PATH)"
    return None


def _version(cxx):
    out = subprocess.run([cxx, "--version"], capture_output=True, text=True, timeout=30).stdout
    return (out.splitlines() or [Path(cxx).name])[0]


def _build(wrapper, include_dirs, compile_error):
    """Path of the shared library of ``wrapper`` (cached per process), and the compile seconds."""
    from . import _slang
    from ._source import ShaderError
    from ._toolchain import run_child

    key = hashlib.sha256("\0".join([wrapper, *map(str, include_dirs)]).encode()).hexdigest()
    if key in _BUILT:
        return _BUILT[key], 0.0
    t0 = time.perf_counter()
    args = ["-target", "cpp", "-entry", "mr_main", "-stage", "compute"]
    for d in include_dirs:
        args += ["-I", str(d)]
    code, log = _slang.compile_slang(wrapper, args)
    if code is None:
        raise compile_error(_slang.errors(log))
    folder = Path(tempfile.mkdtemp(prefix="moments-ref-cpu-"))
    (folder / "port.cpp").write_text(code, encoding="utf-8")
    rc, log = run_child([compiler(), *_FLAGS, "-o", str(folder / "port.so"), str(folder / "port.cpp")],
                        "the C++ compiler")
    if rc != 0:
        first = next((x for x in log.splitlines() if "error" in x), log.strip()[:200])
        raise ShaderError(f"adapter cpu: the C++ compiler refused Slang's cpp output: {first}")
    _BUILT[key] = folder / "port.so"
    return _BUILT[key], time.perf_counter() - t0


def run_cpu(wrapper, include_dirs, compile_error, ins, outs, arrays, n, local_size, time_limit):
    """Build and run a wrapped Slang function on ``n`` rows: ``(results, timings, renderer)``."""
    import numpy as np

    from ._errors import ContextError

    lib, compile_s = _build(wrapper, include_dirs, compile_error)
    groups = -(-n // local_size)
    with tempfile.TemporaryDirectory(prefix="moments-ref-cpu-") as tmp:
        specs, t0 = [], time.perf_counter()
        for k, s in enumerate(ins):
            a = np.ascontiguousarray(np.asarray(arrays[s.name]).astype(s.upload).reshape(n, s.components))
            (Path(tmp) / f"b{k}").write_bytes(a.tobytes())
            specs.append(f"{tmp}/b{k}:{n}:{a.nbytes}:0")
        for k, s in enumerate(outs):
            specs.append(f"{tmp}/o{k}:{n}:{n * s.components * s.upload.itemsize}:1")
        params = np.array([n, groups * local_size, 0, 0], np.uint32)
        (Path(tmp) / "p").write_bytes(params.tobytes())
        specs.append(f"{tmp}/p:4:16:0")
        upload = time.perf_counter() - t0
        t0 = time.perf_counter()
        try:
            proc = subprocess.run([sys.executable, "-S", __file__, str(lib), str(groups), *specs],
                                  capture_output=True, timeout=time_limit)
        except subprocess.TimeoutExpired:
            raise ContextError(f"adapter cpu: the function did not finish within the watchdog's {time_limit:g} s "
                               "(--watchdog)") from None
        if proc.returncode != 0:
            raise ContextError(f"adapter cpu: the compiled port stopped ({proc.returncode}); "
                               f"{proc.stderr.decode('utf-8', 'replace').strip()[-200:]}")
        dispatch = time.perf_counter() - t0
        results = {s.name: np.frombuffer((Path(tmp) / f"o{k}").read_bytes(), dtype=s.upload)
                   .reshape(n, s.components).copy() for k, s in enumerate(outs)}
    renderer = f"CPU: Slang's cpp target, {_version(compiler())} {' '.join(_FLAGS[:3])}"
    return results, {"compile": compile_s, "upload": upload, "dispatch": dispatch, "readback": 0.0}, renderer


def _child(argv):
    """In the child: load the library, bind the buffers, run every work group, write the outputs back."""

    class Buf(ctypes.Structure):
        _fields_ = [("data", ctypes.c_void_p), ("count", ctypes.c_size_t)]

    class Varying(ctypes.Structure):
        _fields_ = [("start", ctypes.c_uint32 * 3), ("end", ctypes.c_uint32 * 3)]

    lib, groups = ctypes.CDLL(argv[0]), int(argv[1])
    keep, bufs = [], []
    for spec in argv[2:]:
        path, count, nbytes, write = spec.rsplit(":", 3)
        data = bytearray(int(nbytes)) if write == "1" else bytearray(Path(path).read_bytes())
        raw = (ctypes.c_char * max(len(data), 1)).from_buffer(data) if data else ctypes.create_string_buffer(1)
        keep.append((path, write, data, raw))
        bufs.append(Buf(ctypes.addressof(raw), int(count)))
    table = (Buf * len(bufs))(*bufs)
    lib.mr_main(ctypes.byref(Varying((0, 0, 0), (groups, 1, 1))), None, ctypes.byref(table))
    for path, write, data, _ in keep:
        if write == "1":
            Path(path).write_bytes(bytes(data))


if __name__ == "__main__":
    _child(sys.argv[1:])
