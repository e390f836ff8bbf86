"""Run a kernel job on OpenGL through moderngl (EGL; Mesa llvmpipe without a GPU). Driver process only.

The context is the driver process's one OpenGL context (:class:`~.._gl.LocalGL`),
shared with the function harness.

The multisampled input is an R32F texture of S samples, filled per sample by a
draw whose fragment shader reads ``gl_SampleID`` (sample-rate shading) and writes
the sample's window depth: a ``sampler2DMS`` fetches it exactly as from a depth
texture (moderngl's depth textures are 24-bit, which would round the depths).
"""

from __future__ import annotations

import time

import numpy as np

from .._errors import LocalCompileError
from ._result import FORMATS, Result

__all__ = ["run"]

_FILL_VS = """#version 430
void main() {
    vec2 xy = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    gl_Position = vec4(xy * 2.0 - 1.0, 0.5, 1.0);
}"""
_FILL_FS = """#version 430
layout(std430, binding = 0) readonly buffer MrSamples { float mr_samples[]; };
uniform uvec3 mr_size;
out float mr_out;
void main() {
    uint x = uint(gl_FragCoord.x), y = uint(gl_FragCoord.y);
    mr_out = mr_samples[(y * mr_size.x + x) * mr_size.z + uint(gl_SampleID)];
}"""


def _ms_texture(ctx, depth):
    """An R32F multisampled texture holding ``depth`` (H, W, S) sample by sample."""
    import moderngl

    h, w, s = depth.shape
    tex = ctx.texture((w, h), 1, samples=s, dtype="f4")
    fbo = ctx.framebuffer(color_attachments=[tex])
    prog = ctx.program(vertex_shader=_FILL_VS, fragment_shader=_FILL_FS)
    prog["mr_size"].value = (w, h, s)
    src = ctx.buffer(np.ascontiguousarray(depth, np.float32).tobytes())
    src.bind_to_storage_buffer(0)
    vao = ctx.vertex_array(prog, [])
    fbo.use()
    ctx.viewport = (0, 0, w, h)
    vao.render(moderngl.TRIANGLES, vertices=3)
    ctx.finish()
    for obj in (vao, prog, fbo, src):
        obj.release()
    return tex


def _point(cs, name, unit, kind):
    """Point the kernel's uniform or block ``name`` at ``unit`` (SPIRV-Cross renames combined samplers)."""
    members = list(cs)
    found = [m for m in members if m == name] or [m for m in members if m.startswith(f"SPIRV_Cross_Combined{name}")]
    for m in found:
        if kind in ("buffer", "uniform"):
            cs[m].binding = unit
        else:
            cs[m].value = unit


def _output(ctx, out):
    if out.kind == "storage_image":
        h, w, c = out.shape
        comps, dt, _ = FORMATS[out.format]
        tex = ctx.texture((w, h), comps, dtype="f4" if dt == np.float32 else "u4")
        tex.write(np.full((h, w, comps), out.fill, np.uint32).tobytes())
        return tex
    return ctx.buffer(np.full(out.shape, out.fill, np.uint32).tobytes())


def run(gl, job, report):
    """Run ``job`` on ``gl`` (a LocalGL); ``report(stage)`` after the compile and after every dispatch (the
    watchdog's heartbeat). Raises LocalCompileError with the driver's log."""
    with gl.ctx:
        return _run(gl.ctx, gl.renderer, job, report)


def _run(ctx, renderer, job, report):
    res = Result(renderer=renderer)
    t0 = time.perf_counter()
    try:
        cs = ctx.compute_shader(job.code)
    except Exception as exc:  # moderngl raises plain Exception subclasses with the driver's log
        raise LocalCompileError(str(exc)) from None
    res.timings["compile"] = time.perf_counter() - t0
    report("compiled")
    t0 = time.perf_counter()
    objects, out_obj, params, trace = _bind(ctx, cs, job)
    ctx.finish()
    res.timings["upload"] = time.perf_counter() - t0
    _dispatch(ctx, cs, job, params, res, report)
    t0 = time.perf_counter()
    res.output = np.frombuffer(out_obj.read(), np.uint32).reshape(job.output.shape).copy()
    if trace is not None:
        res.trace = np.frombuffer(trace.read(), np.uint32).copy()
    res.timings["readback"] = time.perf_counter() - t0
    for obj in objects + [out_obj, params, trace, cs]:
        if obj is not None:
            obj.release()
    return res


def _bind(ctx, cs, job):
    """Create and bind the input, output, uniform block (and trace buffer): ``(objects, output, params, trace)``."""
    objects, out_obj, params = [], None, None
    for b in job.binds:
        if b.role == "input" and b.kind == "texture_ms":
            tex = _ms_texture(ctx, job.data)
            tex.use(b.binding)
            objects.append(tex)
        elif b.role == "input":
            buf = ctx.buffer(np.ascontiguousarray(job.data, np.float32).tobytes())
            buf.bind_to_storage_buffer(b.binding)
            objects.append(buf)
        elif b.role == "output":
            out_obj = _output(ctx, job.output)
            if b.kind == "storage_image":
                out_obj.bind_to_image(b.binding, read=b.access != "write", write=True)
            else:
                out_obj.bind_to_storage_buffer(b.binding)
        else:
            params = ctx.buffer(reserve=len(job.dispatches[0][1]))
            params.bind_to_uniform_block(b.binding)
        _point(cs, b.name, b.binding, b.kind)
    trace = None
    if job.trace_words:
        trace = ctx.buffer(np.zeros(job.trace_words, np.uint32).tobytes())
        trace.bind_to_storage_buffer(7)
        _point(cs, "MrTrace", 7, "buffer")
    return objects, out_obj, params, trace


def _dispatch(ctx, cs, job, params, res, report):
    """The warm-up dispatch, then every dispatch timed by the wall clock (to glFinish).

    No timer queries: llvmpipe answers GL_TIME_ELAPSED with 0 or 1 ns (measured).
    """
    res.timings["dispatch"] = []
    if params is not None:  # warm-up: llvmpipe compiles the kernel at its first dispatch
        params.write(job.dispatches[0][1])
    cs.run(*job.dispatches[0][0])
    ctx.finish()
    report("warm-up")
    for k, (groups, block) in enumerate(job.dispatches):
        if params is not None:
            params.write(block)
        t0 = time.perf_counter()
        cs.run(*groups)
        ctx.memory_barrier()
        ctx.finish()
        res.timings["dispatch"].append(time.perf_counter() - t0)
        report(f"dispatch {k}")
