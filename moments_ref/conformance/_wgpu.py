"""Vulkan backend: wgpu (wgpu-py) on the platform's adapter, Mesa lavapipe without a GPU.

Devices live in the driver process of :mod:`._supervisor`; :func:`get_device`
returns a description and :func:`run_module` sends it work. :func:`dispatch` is
the general backend function there (storage buffers at one bind group, any grid).

WGSL modules and SPIR-V (from glslang) both go through wgpu's shader translator
(naga) to the driver. wgpu's OpenGL adapter (EGL, llvmpipe) runs the same WGSL
on OpenGL. Requirements: ``pip install wgpu`` and a Vulkan driver (Debian/Ubuntu:
``apt-get install mesa-vulkan-drivers libvulkan1``).
"""

from __future__ import annotations

import hashlib
import logging
import os
import re
import time

from ._errors import ContextError, LocalCompileError
from ._source import WRAPPER, wrapped_compile_error

__all__ = ["RemoteDevice", "LocalDevice", "get_device", "adapters", "run_module", "open_local", "dispatch", "load_wgpu",
           "KERNEL_LIMITS", "FEATURES"]

_DEVICES = {}
_PIPELINES = {}
_HINT = "install the Python package 'wgpu' and a Vulkan driver (Debian/Ubuntu: apt-get install mesa-vulkan-drivers)"


def load_wgpu():
    """The ``wgpu`` module, quiet; :class:`ContextError` (with the packages to install) without it."""
    os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp")  # silences Mesa's warning on headless machines
    try:
        import wgpu
    except ImportError as exc:
        raise ContextError(f"wgpu is not importable ({exc}); {_HINT}") from None
    # naga warns "Unknown decoration NoContraction" for every `precise` of SPIR-V input
    # (docs/ports.md says what that means); the report states it once instead.
    logging.getLogger("wgpu").setLevel(logging.ERROR)
    return wgpu


def adapters():
    """``[(backend, device name, description)]`` of every adapter wgpu finds (in this process)."""
    wgpu = load_wgpu()
    return [(a.info.get("backend_type"), a.info.get("device"), a.info.get("description"))
            for a in wgpu.gpu.enumerate_adapters_sync()]


class RemoteDevice:
    """A wgpu device of the driver process (:mod:`._supervisor`): backend, adapter name asked for, renderer."""

    def __init__(self, backend, name, renderer):
        self.backend, self.name, self.renderer = backend, name, renderer

    @property
    def target(self):
        return ("wgpu", self.backend, self.name)


def get_device(backend="Vulkan", name=None):
    """The device on the first adapter of ``backend`` whose name contains ``name``, in the driver process.

    Raises :class:`ContextError` when there is none (naming the adapters found).
    """
    key = (backend, name)
    if key not in _DEVICES:
        from ._dispatch import open_target

        renderer = open_target(("wgpu", backend, name))[0]
        _DEVICES[key] = RemoteDevice(backend, name, renderer)
    return _DEVICES[key]


def _wgsl_errors(text, locate):
    """naga's message as one line per error: ``file:line:col: message``, then its labels and notes.

    Parse errors point at ``wgsl:LINE:COL``, validation errors (a call that does not
    match the function) at ``:LINE:COL``; the block under the location holds the
    label under the carets and ``= note`` lines.
    """
    msgs = re.findall(r"(?:error|Error)[^:\n]*:\s*([^\n]+)\n\s*┌─ (?:wgsl)?:(\d+):(\d+)((?:\n[^\n]*\S[^\n]*)*)", text)
    if not msgs:
        return [" ".join(line.strip() for line in text.splitlines() if line.strip())]
    out = []
    for msg, line, col, block in msgs:
        msg = msg.strip()
        more = [x.strip() for x in re.findall(r"\^+([^\n]+)", block) + re.findall(r"^\s*= ([^\n]+)", block, re.M)]
        more = [x for x in dict.fromkeys(more) if x and x not in msg]
        where = locate(int(line))
        where = where if where == WRAPPER else f"{where}:{col}"  # the wrapper's own lines have no file to open
        out.append(f"{where}: {msg}" + (f": {'; '.join(more)}" if more else ""))
    return out


def run_module(dev, code, group, locate, signature, ins, outs, arrays, n, local_size, entry="mr_main", tex=None):
    """Compile (cached) and dispatch a WGSL (str) or SPIR-V (bytes) module at ``entry`` in the driver process."""
    from ._dispatch import dispatch
    from ._gl import case_bindings, case_results

    bindings, grid = case_bindings(ins, outs, arrays, n, local_size, tex)

    def failed(text):
        lines = _wgsl_errors(text, locate) if isinstance(code, str) else [
            " ".join(x.strip() for x in text.splitlines() if x.strip())]
        return wrapped_compile_error("WGSL" if isinstance(code, str) else "SPIR-V (naga)", lines, signature)

    raw, timings = dispatch(dev.target, code, bindings, grid, entry, group, on_compile_error=failed)
    return case_results(outs, ins, raw, n), timings


# ----------------------------------------------------------------------------------------
# In the driver process
# ----------------------------------------------------------------------------------------

#: Limits a device asks of its adapter (the adapter's own maximum): the shipped filter kernels keep
#: 32 KiB in workgroup storage with 256 invocations per work group; a bench map's buffers are large.
KERNEL_LIMITS = ("max-compute-workgroup-storage-size", "max-compute-invocations-per-workgroup",
                 "max-storage-buffer-binding-size")
#: Features a device takes where its adapter has them: 16-bit normalized textures (64-bit moment
#: maps as textures), timestamp queries (a kernel's own dispatch time), filterable float32 textures
#: (bilinear cases).
FEATURES = ("texture-format16bit-norm", "timestamp-query", "float32-filterable")
#: The feature a linearly filtered rgba32float texture (a bilinear case) needs.
FILTERABLE = "float32-filterable"


class LocalDevice:
    """A wgpu device inside the driver process, for functions and kernels: compile (explicit layouts) and dispatch."""

    def __init__(self, adapter):
        self.adapter = adapter
        self.device = adapter.request_device_sync(
            required_features=[f for f in FEATURES if f in adapter.features],
            required_limits={k: adapter.limits[k] for k in KERNEL_LIMITS if k in adapter.limits})
        info = adapter.info
        self.backend = info.get("backend_type", "?")
        self.renderer = f"{info.get('device', '?')}, {info.get('description', '?')} ({self.backend} through wgpu)"
        self.version_code = 0

    def compile(self, code, entry, group, modes):
        key = (id(self), entry, group, tuple(modes), hashlib.sha256(code if isinstance(code, bytes) else code.encode()).hexdigest())
        if key not in _PIPELINES:
            if any(k.endswith(":linear") for _, k in modes) and FILTERABLE not in self.device.features:
                raise ContextError(f"the adapter {self.renderer} lacks the WebGPU feature '{FILTERABLE}', which a "
                                   "linear sampler on an rgba32float texture (a bilinear case) needs; choose another "
                                   "adapter (--adapter vulkan: Mesa lavapipe has it)")
            try:
                module = self.device.create_shader_module(code=code)
                layout, layouts = _layout(self, group, modes)
                _PIPELINES[key] = (self.device.create_compute_pipeline(
                    layout=layout, compute={"module": module, "entry_point": entry}), layouts)
            except Exception as exc:
                raise LocalCompileError(str(exc)) from None
        return _PIPELINES[key]

    def dispatch(self, compiled, bindings, grid, group):
        return dispatch(self, compiled, bindings, grid, group)


def open_local(backend="Vulkan", name=None):
    """A :class:`LocalDevice` on the first matching adapter (in the driver process)."""
    wgpu = load_wgpu()
    try:
        found = wgpu.gpu.enumerate_adapters_sync()
    except Exception as exc:
        raise ContextError(f"wgpu finds no adapter: {type(exc).__name__}: {exc}; {_HINT}") from None
    for a in found:
        info = a.info
        if info.get("backend_type") == backend and (name is None or name.lower() in
                                                    f"{info.get('device')} {info.get('vendor')}".lower()):
            return LocalDevice(a)
    have = "; ".join(f"{a.info.get('backend_type')}: {a.info.get('device')}" for a in found) or "none"
    want = backend + (f" adapter matching {name!r}" if name else " adapter")
    raise ContextError(f"no {want} (wgpu found: {have}); {_HINT}")


def _layout(dev, group, modes):
    """Explicit pipeline layout: empty groups below ``group``, then storage buffers ``modes``.

    ``modes`` are ``(binding, kind)``: ``"read"``, ``"write"``, ``"texture:FORMAT"`` or ``"sampler"``. An explicit layout
    (not ``"auto"``) keeps bindings the compiled function does not read (an
    argument it ignores) in the layout, so that the bind group always matches it.
    """
    wgpu = load_wgpu()
    types = {"read": wgpu.BufferBindingType.read_only_storage, "write": wgpu.BufferBindingType.storage}
    d = dev.device
    empty = d.create_bind_group_layout(entries=[])
    own = d.create_bind_group_layout(entries=[_entry(wgpu, b, k, types) for b, k in modes])
    layouts = [empty] * group + [own]
    return d.create_pipeline_layout(bind_group_layouts=layouts), layouts


def _entry(wgpu, b, kind, types):
    """A bind group layout entry: a storage buffer, a texture (unfiltered float or uint; filterable float for a
    bilinear case), a point or linear sampler."""
    if kind.startswith("sampler"):
        return {"binding": b, "visibility": wgpu.ShaderStage.COMPUTE,
                "sampler": {"type": "filtering" if kind.endswith(":linear") else "non-filtering"}}
    if kind.startswith("texture:"):
        sample = "uint" if kind.endswith("uint") else "float" if kind.endswith(":linear") else "unfilterable-float"
        return {"binding": b, "visibility": wgpu.ShaderStage.COMPUTE,
                "texture": {"sample_type": sample, "view_dimension": "2d", "multisampled": False}}
    return {"binding": b, "visibility": wgpu.ShaderStage.COMPUTE, "buffer": {"type": types[kind]}}


def _sampler(d, mode):
    """A point sampler, or a linear one (``sampler:linear``); clamped to the edge, one mipmap level."""
    f = "linear" if mode.endswith(":linear") else "nearest"
    return d.create_sampler(mag_filter=f, min_filter=f, address_mode_u="clamp-to-edge", address_mode_v="clamp-to-edge")


def _texture(d, wgpu, b):
    w, h, fmt = b.texture[:3]
    tex = d.create_texture(size=(w, h, 1), format=fmt,
                           usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST)
    d.queue.write_texture({"texture": tex, "mip_level": 0, "origin": (0, 0, 0)}, b.data,
                          {"offset": 0, "bytes_per_row": len(b.data) // h, "rows_per_image": h}, (w, h, 1))
    return tex


def dispatch(dev, compiled, bindings, grid, group):
    """Bind storage buffers (:class:`~._dispatch.Binding`) at ``group``, dispatch ``grid``, read back.

    Returns ``({binding: bytes} of the "write" buffers, timings)``.
    """
    wgpu = load_wgpu()
    d = dev.device
    pipe, layouts = compiled
    timings = {"compile": 0.0}
    t0 = time.perf_counter()
    storage = wgpu.BufferUsage.STORAGE
    bufs = [(b, _texture(d, wgpu, b) if b.mode == "texture" else _sampler(d, b.mode) if b.mode.startswith("sampler") else
             d.create_buffer_with_data(data=b.data, usage=storage | wgpu.BufferUsage.COPY_SRC)
             if b.data is not None else d.create_buffer(size=b.size, usage=storage | wgpu.BufferUsage.COPY_SRC))
            for b in sorted(bindings, key=lambda b: b.binding)]
    entries = [{"binding": b.binding, "resource": buf.create_view() if b.mode == "texture" else
                buf if b.mode.startswith("sampler") else {"buffer": buf}} for b, buf in bufs]
    binds = [d.create_bind_group(layout=lay, entries=[]) for lay in layouts[:group]]
    binds.append(d.create_bind_group(layout=layouts[group], entries=entries))
    timings["upload"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    enc = d.create_command_encoder()
    cpass = enc.begin_compute_pass()
    cpass.set_pipeline(pipe)
    for g, bind in enumerate(binds):
        cpass.set_bind_group(g, bind)
    cpass.dispatch_workgroups(*grid)
    cpass.end()
    d.queue.submit([enc.finish()])
    timings["dispatch"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    out = {b.binding: bytes(d.queue.read_buffer(buf)) for b, buf in bufs if b.mode == "write"}
    timings["readback"] = time.perf_counter() - t0
    for b, buf in bufs:
        if not b.mode.startswith("sampler"):
            buf.destroy()
    return out, timings
