"""Run a kernel job through wgpu: Vulkan (Mesa lavapipe without a GPU) or wgpu's OpenGL adapter. Driver process only.

The device is the driver process's one device of the adapter (:class:`~.._wgpu.LocalDevice`, shared
with the function harness; it asks for the limits the kernels need).

The pipeline layout is built from the kernel's declarations (not derived by
wgpu), so a declared binding the kernel never uses is still bound. The
multisampled input is a Depth32Float texture of S samples, filled per sample by a
draw that writes ``frag_depth`` at each ``sample_index``; it binds both as
``texture_depth_multisampled_2d`` and as ``texture_multisampled_2d<f32>``
(unfilterable float).
"""

from __future__ import annotations

import time

import numpy as np

from .._errors import LocalCompileError
from .._wgpu import load_wgpu
from ._result import FORMATS, Result

__all__ = ["run"]

_FILL = """
@group(0) @binding(0) var<storage, read> mr_samples: array<f32>;
@group(0) @binding(1) var<uniform> mr_size: vec4<u32>;
@vertex fn mr_vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let xy = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(xy * 2.0 - 1.0, 0.5, 1.0);
}
struct MrOut { @builtin(frag_depth) depth: f32 };
@fragment fn mr_fs(@builtin(position) pos: vec4<f32>, @builtin(sample_index) s: u32) -> MrOut {
    let x = u32(pos.x);
    let y = u32(pos.y);
    var o: MrOut;
    o.depth = mr_samples[(y * mr_size.x + x) * mr_size.z + s];
    return o;
}
"""


def _ms_texture(wgpu, dev, depth):
    h, w, s = depth.shape
    usage = wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.TEXTURE_BINDING
    tex = dev.create_texture(size=(w, h, 1), sample_count=s, format="depth32float", usage=usage)
    module = dev.create_shader_module(code=_FILL)
    pipe = dev.create_render_pipeline(
        layout="auto", vertex={"module": module, "entry_point": "mr_vs"}, primitive={"topology": "triangle-list"},
        depth_stencil={"format": "depth32float", "depth_write_enabled": True, "depth_compare": "always"},
        multisample={"count": s}, fragment={"module": module, "entry_point": "mr_fs", "targets": []})
    src = dev.create_buffer_with_data(data=np.ascontiguousarray(depth, np.float32).tobytes(),
                                      usage=wgpu.BufferUsage.STORAGE)
    size = dev.create_buffer_with_data(data=np.array([w, h, s, 0], np.uint32).tobytes(),
                                       usage=wgpu.BufferUsage.UNIFORM)
    bind = dev.create_bind_group(layout=pipe.get_bind_group_layout(0), entries=[
        {"binding": 0, "resource": {"buffer": src}}, {"binding": 1, "resource": {"buffer": size}}])
    enc = dev.create_command_encoder()
    rp = enc.begin_render_pass(color_attachments=[], depth_stencil_attachment={
        "view": tex.create_view(), "depth_clear_value": 0.0, "depth_load_op": "clear", "depth_store_op": "store"})
    rp.set_pipeline(pipe)
    rp.set_bind_group(0, bind)
    rp.draw(3)
    rp.end()
    dev.queue.submit([enc.finish()])
    return tex


def _layout_entry(wgpu, b):
    e = {"binding": b.binding, "visibility": wgpu.ShaderStage.COMPUTE}
    if b.kind == "texture_ms":
        e["texture"] = {"sample_type": "depth" if b.depth else "unfilterable-float", "view_dimension": "2d",
                        "multisampled": True}
    elif b.kind == "storage_image":
        access = {"write": "write-only", "read": "read-only", "read_write": "read-write"}[b.access]
        e["storage_texture"] = {"access": access, "format": FORMATS[b.format][2], "view_dimension": "2d"}
    elif b.kind == "uniform":
        e["buffer"] = {"type": "uniform"}
    else:
        e["buffer"] = {"type": "read-only-storage" if b.access == "read" else "storage"}
    return e


def _pipeline(wgpu, dev, job):
    sets = max([b.set for b in job.binds] + [0])
    entries = {s: [_layout_entry(wgpu, b) for b in job.binds if b.set == s] for s in range(sets + 1)}
    if job.trace_words:
        entries.setdefault(3, [])
        entries[3].append({"binding": 7, "visibility": wgpu.ShaderStage.COMPUTE, "buffer": {"type": "storage"}})
        for s in range(sets + 1, 4):
            entries.setdefault(s, [])
    layouts = [dev.create_bind_group_layout(entries=entries[s]) for s in sorted(entries)]
    module = dev.create_shader_module(code=job.code)
    pipe = dev.create_compute_pipeline(layout=dev.create_pipeline_layout(bind_group_layouts=layouts),
                                       compute={"module": module, "entry_point": job.entry})
    return pipe, layouts


def _output(wgpu, dev, out):
    if out.kind == "storage_image":
        h, w, c = out.shape
        usage = wgpu.TextureUsage.STORAGE_BINDING | wgpu.TextureUsage.COPY_SRC | wgpu.TextureUsage.COPY_DST
        tex = dev.create_texture(size=(w, h, 1), format=FORMATS[out.format][2], usage=usage)
        dev.queue.write_texture({"texture": tex}, np.full((h, w, c), out.fill, np.uint32).tobytes(),
                                {"bytes_per_row": w * c * 4, "rows_per_image": h}, (w, h, 1))
        return tex
    return dev.create_buffer_with_data(data=np.full(out.shape, out.fill, np.uint32).tobytes(),
                                       usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)


def _read(dev, obj, out):
    if out.kind == "storage_image":
        h, w, c = out.shape
        data = dev.queue.read_texture({"texture": obj}, {"bytes_per_row": w * c * 4, "rows_per_image": h}, (w, h, 1))
        return np.frombuffer(data, np.uint32).reshape(h, w, c).copy()
    return np.frombuffer(dev.queue.read_buffer(obj), np.uint32).copy()


def run(device, job, report):
    """Run ``job`` on ``device`` (a LocalDevice); ``report(stage)`` after the compile and every dispatch.
    Raises LocalCompileError with naga's or the driver's message."""
    wgpu = load_wgpu()
    dev = device.device
    res = Result(renderer=device.renderer)
    t0 = time.perf_counter()
    try:
        pipe, layouts = _pipeline(wgpu, dev, job)
    except Exception as exc:  # wgpu's validation errors carry naga's message
        raise LocalCompileError(str(exc)) from None
    res.timings["compile"] = time.perf_counter() - t0
    report("compiled")
    t0 = time.perf_counter()
    out_obj = _output(wgpu, dev, job.output)
    resources, params, trace = _resources(wgpu, dev, job, out_obj)
    res.timings["upload"] = time.perf_counter() - t0
    _dispatch(wgpu, dev, job, pipe, layouts, resources, params, res, report)
    t0 = time.perf_counter()
    res.output = _read(dev, out_obj, job.output)
    if trace is not None:
        res.trace = np.frombuffer(dev.queue.read_buffer(trace), np.uint32).copy()
    res.timings["readback"] = time.perf_counter() - t0
    return res


def _resources(wgpu, dev, job, out_obj):
    """``({(set, binding): resource}, params (set, binding) or None, trace buffer or None)``."""
    resources, params = {}, None
    for b in job.binds:
        if b.role == "input" and b.kind == "texture_ms":
            resources[(b.set, b.binding)] = _ms_texture(wgpu, dev, job.data).create_view()
        elif b.role == "input":
            buf = dev.create_buffer_with_data(data=np.ascontiguousarray(job.data, np.float32).tobytes(),
                                              usage=wgpu.BufferUsage.STORAGE)
            resources[(b.set, b.binding)] = {"buffer": buf}
        elif b.role == "output":
            resources[(b.set, b.binding)] = out_obj.create_view() if b.kind == "storage_image" else {"buffer": out_obj}
        else:
            params = (b.set, b.binding)
    trace = None
    if job.trace_words:
        trace = dev.create_buffer_with_data(data=np.zeros(job.trace_words, np.uint32).tobytes(),
                                            usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)
        resources[(3, 7)] = {"buffer": trace}
    return resources, params, trace


def _dispatch(wgpu, dev, job, pipe, layouts, resources, params, res, report):
    """The warm-up dispatch, then every dispatch timed (wall clock and timestamp queries)."""
    res.timings["dispatch"], res.timings["driver"] = [], []
    fence = dev.create_buffer(size=4, usage=wgpu.BufferUsage.COPY_SRC | wgpu.BufferUsage.STORAGE)
    stamps = None
    if "timestamp-query" in dev.features:  # the compute pass's own time, without wgpu's overhead
        stamps = (dev.create_query_set(type="timestamp", count=2),
                  dev.create_buffer(size=16, usage=wgpu.BufferUsage.QUERY_RESOLVE | wgpu.BufferUsage.COPY_SRC))
    for k, (groups, block) in [(-1, job.dispatches[0])] + list(enumerate(job.dispatches)):
        t0 = time.perf_counter()
        if params is not None:
            resources[params] = {"buffer": dev.create_buffer_with_data(data=block, usage=wgpu.BufferUsage.UNIFORM)}
        enc = dev.create_command_encoder()
        cp = enc.begin_compute_pass(timestamp_writes=None if stamps is None else {
            "query_set": stamps[0], "beginning_of_pass_write_index": 0, "end_of_pass_write_index": 1})
        cp.set_pipeline(pipe)
        for s, layout in enumerate(layouts):
            entries = [{"binding": b, "resource": r} for (ss, b), r in sorted(resources.items()) if ss == s]
            cp.set_bind_group(s, dev.create_bind_group(layout=layout, entries=entries))
        cp.dispatch_workgroups(*groups)
        cp.end()
        if stamps is not None:
            enc.resolve_query_set(stamps[0], 0, 2, stamps[1], 0)
        dev.queue.submit([enc.finish()])
        if stamps is not None:
            ts = np.frombuffer(dev.queue.read_buffer(stamps[1]), np.uint64)
        else:
            dev.queue.read_buffer(fence)  # waits for the queue (on_submitted_work_done is broken in wgpu-py 0.32)
        if k < 0:  # warm-up: lavapipe may compile the pipeline at its first dispatch
            report("warm-up")
            continue
        if stamps is not None:
            res.timings["driver"].append(float(ts[1] - ts[0]) * 1e-9)
        res.timings["dispatch"].append(time.perf_counter() - t0)
        report(f"dispatch {k}")
