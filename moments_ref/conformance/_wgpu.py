"""Vulkan backend: wgpu (wgpu-py) on the platform's adapter, Mesa lavapipe without a GPU.

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

import numpy as np

from ._gl import ContextError, groups
from ._slots import as_buffer
from ._source import ShaderError

__all__ = ["Device", "get_device", "adapters", "run_module"]

_DEVICES = {}
_PIPELINES = {}
_HINT = "install the Python package 'wgpu' and a Vulkan driver (Debian/Ubuntu: apt-get install mesa-vulkan-drivers)"


class Device:
    """A wgpu device on one adapter, with the adapter's description."""

    def __init__(self, adapter):
        self.adapter = adapter
        self.device = adapter.request_device_sync()
        info = adapter.info
        self.backend = info.get("backend_type", "?")
        self.renderer = f"{info.get('device', '?')}, {info.get('description', '?')} ({self.backend} through wgpu)"


def _wgpu():
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
    """``[(backend, device name, description)]`` of every adapter wgpu finds."""
    wgpu = _wgpu()
    return [(a.info.get("backend_type"), a.info.get("device"), a.info.get("description"))
            for a in wgpu.gpu.enumerate_adapters_sync()]


def get_device(backend="Vulkan", name=None):
    """The cached device on the first adapter of ``backend`` whose name contains ``name``.

    Raises :class:`ContextError` when there is none (naming the adapters found).
    """
    key = (backend, name)
    if key not in _DEVICES:
        wgpu = _wgpu()
        try:
            found = wgpu.gpu.enumerate_adapters_sync()
        except Exception as exc:
            raise ContextError(f"wgpu finds no adapter: {type(exc).__name__}: {exc}; {_HINT}") from None
        for a in found:
            info = a.info
            if info.get("backend_type") == backend and (name is None or name.lower() in
                                                        f"{info.get('device')} {info.get('vendor')}".lower()):
                _DEVICES[key] = Device(a)
                break
        else:
            have = "; ".join(f"{a.info.get('backend_type')}: {a.info.get('device')}" for a in found) or "none"
            want = backend + (f" adapter matching {name!r}" if name else " adapter")
            raise ContextError(f"no {want} (wgpu found: {have}); {_HINT}")
    return _DEVICES[key]


def _wgsl_errors(text, locate):
    """naga's message as one line per error: ``file:line:col: message``."""
    msgs = re.findall(r"(?:error|Error)[^:\n]*:\s*([^\n]+)\n\s*┌─ wgsl:(\d+):(\d+)", text)
    if not msgs:
        return [" ".join(line.strip() for line in text.splitlines() if line.strip())]
    return [f"{locate(int(line))}:{col}: {msg.strip()}" for msg, line, col in msgs]


def _layout(dev, group, kinds):
    """Explicit pipeline layout: empty groups below ``group``, then the harness's buffers.

    ``kinds[b]`` is ``"read"`` or ``"write"`` for binding ``b``. An explicit layout
    (not ``"auto"``) keeps bindings the compiled function does not read (its
    argument ignored) in the layout, so that the bind group always matches it.
    """
    wgpu = _wgpu()
    types = {"read": wgpu.BufferBindingType.read_only_storage, "write": wgpu.BufferBindingType.storage}
    d = dev.device
    empty = d.create_bind_group_layout(entries=[])
    own = d.create_bind_group_layout(entries=[
        {"binding": b, "visibility": wgpu.ShaderStage.COMPUTE, "buffer": {"type": types[k]}}
        for b, k in enumerate(kinds)])
    layouts = [empty] * group + [own]
    return d.create_pipeline_layout(bind_group_layouts=layouts), layouts


def _pipeline(dev, code, locate, signature, entry, group, kinds):
    key = (id(dev), entry, group, tuple(kinds),
           hashlib.sha256(code if isinstance(code, bytes) else code.encode()).hexdigest())
    if key not in _PIPELINES:
        try:
            module = dev.device.create_shader_module(code=code)
            layout, layouts = _layout(dev, group, kinds)
            _PIPELINES[key] = (dev.device.create_compute_pipeline(
                layout=layout, compute={"module": module, "entry_point": entry}), layouts)
        except Exception as exc:
            text = str(exc)
            lines = _wgsl_errors(text, locate) if isinstance(code, str) else [
                " ".join(x.strip() for x in text.splitlines() if x.strip())]
            kind = "WGSL" if isinstance(code, str) else "SPIR-V (naga)"
            raise ShaderError(f"the wrapped function does not compile ({kind}; expected signature: {signature}):\n"
                              + "\n".join(lines)) from None
    return _PIPELINES[key]


def run_module(dev, code, group, locate, signature, ins, outs, arrays, n, local_size, entry="mr_main"):
    """Compile (cached) and dispatch a WGSL (str) or SPIR-V (bytes) module at ``entry``."""
    wgpu = _wgpu()
    d = dev.device
    timings = {}
    t0 = time.perf_counter()
    kinds = ["read"] * len(ins) + ["write"] * len(outs) + ["read"]
    pipe, layouts = _pipeline(dev, code, locate, signature, entry, group, kinds)
    timings["compile"] = time.perf_counter() - t0
    gx, gy = groups(n, local_size)
    t0 = time.perf_counter()
    storage = wgpu.BufferUsage.STORAGE
    bufs = [d.create_buffer_with_data(data=as_buffer(arrays[s.name], s).tobytes(), usage=storage) for s in ins]
    out_bufs = [d.create_buffer(size=max(16, n * s.width * 4), usage=storage | wgpu.BufferUsage.COPY_SRC)
                for s in outs]
    params = d.create_buffer_with_data(data=np.array([n, gx * local_size, 0, 0], np.uint32).tobytes(), usage=storage)
    entries = [{"binding": b, "resource": {"buffer": buf}} for b, buf in enumerate(bufs + out_bufs + [params])]
    binds = [d.create_bind_group(layout=lay, entries=[]) for lay in layouts[:group]]
    binds.append(d.create_bind_group(layout=layouts[group], entries=entries))
    timings["upload"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    enc = d.create_command_encoder()
    cpass = enc.begin_compute_pass()
    cpass.set_pipeline(pipe)
    for g, bind in enumerate(binds):
        cpass.set_bind_group(g, bind)
    cpass.dispatch_workgroups(gx, gy, 1)
    cpass.end()
    d.queue.submit([enc.finish()])
    timings["dispatch"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    results = {s.name: np.frombuffer(d.queue.read_buffer(buf), dtype=s.upload)[: n * s.width]
               .reshape(n, s.width)[:, : s.components].copy() for s, buf in zip(outs, out_bufs)}
    timings["readback"] = time.perf_counter() - t0
    for buf in bufs + out_bufs + [params]:
        buf.destroy()
    return results, timings
