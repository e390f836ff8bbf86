"""Mesa's llvmpipe (OpenGL on the CPU) drawing the bench's triangles, one thread, in a worker process.

The worker is started with ``LP_NUM_THREADS=0`` (llvmpipe rasterizes in the
calling thread) so that its CPU time is one core's work, like the reference's.
It builds the same scenes as :mod:`moments_ref.tools.bench._cases` (same seeds), so
only short commands cross the pipe: ``case NAME`` sets a scene up (vertices in
clip space from the same ``clip_from_world``, a depth-only multisampled framebuffer,
a warm-up draw for the shader JIT), ``time`` clears, draws and waits
(``glFinish``) once and answers ``{"wall": s, "cpu": s}``. Upload and readback
are outside the timing; the reference's timing includes its vertex transform
and the depth map it returns.

The parent alternates its own runs with the worker's (:class:`Llvmpipe`), so
the load of the shared machine reaches both sides.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

__all__ = ["Llvmpipe", "LlvmpipeUnavailable"]


class LlvmpipeUnavailable(RuntimeError):
    """No llvmpipe worker (moderngl, EGL or the driver missing); ``str(exc)`` says why."""


_VERTEX = "#version 330\nin vec4 p;\nvoid main() { gl_Position = p; }\n"
_FRAGMENT = "#version 330\nvoid main() {}\n"


def _gl_case(ctx, name):
    """Upload scene ``name`` and return ``(draw, renderer)``."""
    import moderngl

    from ._cases import raster_case

    v, t, vp, size, samples = raster_case(name)
    clip = (np.c_[v, np.ones(len(v))] @ np.asarray(vp, np.float64).T).astype(np.float32)
    prog = ctx.program(vertex_shader=_VERTEX, fragment_shader=_FRAGMENT)
    vbo = ctx.buffer(clip.tobytes())
    ibo = ctx.buffer(np.asarray(t, np.uint32).tobytes())
    vao = ctx.vertex_array(prog, [(vbo, "4f", "p")], index_buffer=ibo, index_element_size=4)
    depth = ctx.depth_renderbuffer((size, size), samples=samples if samples > 1 else 0)
    fbo = ctx.framebuffer(depth_attachment=depth)
    fbo.use()
    ctx.enable(moderngl.DEPTH_TEST)
    ctx.depth_func = "<"

    def draw():
        fbo.clear(depth=1.0)
        vao.render(moderngl.TRIANGLES)
        ctx.finish()

    draw()  # the shader JIT and first-touch of the framebuffer, outside the timing
    return draw, (prog, vbo, ibo, vao, depth, fbo)


def serve(stdin=sys.stdin, stdout=sys.stdout):
    """The worker's loop (``python -m moments_ref.tools.bench._llvmpipe``)."""
    import moderngl

    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=330)
    except Exception as exc:  # moderngl raises plain Exception subclasses for EGL failures
        print(json.dumps({"error": f"no EGL context: {type(exc).__name__}: {exc}"}), file=stdout, flush=True)
        return
    print(json.dumps({"renderer": ctx.info.get("GL_RENDERER", "?"),
                      "threads": os.environ.get("LP_NUM_THREADS")}), file=stdout, flush=True)
    draw, keep = None, None
    for line in stdin:
        cmd, _, arg = line.strip().partition(" ")
        if cmd == "case":
            draw, keep = _gl_case(ctx, arg)
            print(json.dumps({"ok": arg}), file=stdout, flush=True)
        elif cmd == "time":
            c0, t0 = time.process_time(), time.perf_counter()
            draw()
            print(json.dumps({"wall": time.perf_counter() - t0, "cpu": time.process_time() - c0}),
                  file=stdout, flush=True)
        else:
            break
    del keep
    ctx.release()


class Llvmpipe:
    """A worker process running llvmpipe with ``LP_NUM_THREADS=0``; ``with Llvmpipe() as lp: ...``.

    Raises :class:`LlvmpipeUnavailable` (with the reason) when moderngl is not
    importable or the worker gets no EGL context.
    """

    def __init__(self):
        try:
            import moderngl  # noqa: F401
        except ImportError as exc:
            raise LlvmpipeUnavailable(f"moderngl is not importable ({exc})") from None
        env = dict(os.environ, LP_NUM_THREADS="0", GALLIUM_DRIVER="llvmpipe")
        root = str(Path(__file__).resolve().parents[3])
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        self._p = subprocess.Popen([sys.executable, "-m", "moments_ref.tools.bench._llvmpipe"], env=env,
                                   stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        hello = self._read()
        if "error" in hello:
            self.close()
            raise LlvmpipeUnavailable(hello["error"])
        self.renderer = hello["renderer"]

    def _read(self):
        line = self._p.stdout.readline()
        if not line:
            raise LlvmpipeUnavailable(f"the llvmpipe worker exited (code {self._p.wait()})")
        return json.loads(line)

    def _ask(self, text):
        self._p.stdin.write(text + "\n")
        self._p.stdin.flush()
        return self._read()

    def case(self, name):
        """Set scene ``name`` of :func:`moments_ref.tools.bench._cases.raster_case` up in the worker."""
        self._ask(f"case {name}")

    def time(self):
        """One timed draw: ``{"wall": s, "cpu": s}``."""
        return self._ask("time")

    def close(self):
        if self._p.poll() is None:
            self._p.stdin.write("quit\n")
            self._p.stdin.close()
            self._p.wait(timeout=60)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


if __name__ == "__main__":
    serve()
