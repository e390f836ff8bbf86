"""A function's dispatch as a job of the driver process (:mod:`._supervisor`).

The backend functions (:func:`._gl.dispatch`, :func:`._wgpu.dispatch`) are general:
they bind any list of resources (:class:`Binding`: storage buffers, textures,
samplers), dispatch a given grid and read back the writable buffers. Here they run
in the driver process: :func:`open_target` starts a driver there, :func:`dispatch`
compiles (the compile time limit) and dispatches (the watchdog) one shader.
"""

from __future__ import annotations

from dataclasses import dataclass

from ._supervisor import COMPILE_SECONDS, CompileFailed, DriverError, run, watchdog

__all__ = ["Binding", "open_target", "dispatch"]


@dataclass(frozen=True)
class Binding:
    """One storage buffer: ``binding`` index, initial bytes (or None: ``size`` zero bytes), and
    ``mode`` ``"read"`` (read-only in the shader) or ``"write"`` (read back after the dispatch);
    or a 2-D texture (``mode`` ``"texture"``, ``texture`` = (width, height, WebGPU format name),
    ``data`` its texels; a fourth entry ``"linear"``: filtered, a bilinear case); or a sampler (``mode``
    ``"sampler"``, point, or ``"sampler:linear"``)."""

    binding: int
    data: bytes | None
    size: int
    mode: str = "read"
    texture: tuple | None = None

    @property
    def kind(self):
        """``read``, ``write``, ``texture:FORMAT[:linear]`` or ``sampler[:linear]`` (what a pipeline layout needs)."""
        return ":".join(("texture",) + tuple(self.texture[2:])) if self.mode == "texture" else self.mode


@dataclass(frozen=True)
class _Open:
    """Start a driver; answers ``(renderer, version_code, takes SPIR-V)``."""

    target: tuple

    def step(self, done):
        return "the driver's start", COMPILE_SECONDS, False

    def run(self, drivers, beat):
        d = drivers.open(self.target)
        return d.renderer, d.version_code, getattr(d, "spirv", False)


@dataclass(frozen=True)
class _Dispatch:
    """Compile (cached in the driver process) and dispatch one shader; answers ``(outputs, timings)``."""

    target: tuple
    code: object
    bindings: tuple
    groups: tuple
    entry: str
    group: int
    seconds: float

    def step(self, done):
        return ("the compile", COMPILE_SECONDS, False) if done is None else ("the dispatch", self.seconds, True)

    def run(self, drivers, beat):
        driver = drivers.open(self.target)
        modes = [(b.binding, b.kind) for b in sorted(self.bindings, key=lambda b: b.binding)]
        compiled = driver.compile(self.code, self.entry, self.group, modes)
        beat("compiled")
        return driver.dispatch(compiled, self.bindings, self.groups, self.group)


def open_target(target):
    """``(renderer, version_code, takes SPIR-V)`` of ``target`` (``("gl",)`` or ``("wgpu", backend, name)``).

    Raises :class:`~._errors.ContextError` when there is no such driver.
    """
    return run(_Open(target))


def dispatch(target, code, bindings, groups, entry="main", group=0, on_compile_error=None):
    """Compile ``code`` (GLSL text for ``("gl",)``; WGSL text or SPIR-V bytes for wgpu) and dispatch it.

    Parameters
    ----------
    target : tuple
        ``("gl",)`` or ``("wgpu", backend, adapter name or None)``.
    bindings : list of Binding
    groups : (gx, gy, gz)
    entry, group : wgpu only: entry point, and the bind group of the bindings.
    on_compile_error : callable(raw log) -> Exception, optional

    Returns
    -------
    (dict binding -> bytes of the "write" buffers, timings dict)
    """
    try:
        return run(_Dispatch(target, code, tuple(bindings), tuple(groups), entry, group, watchdog()))
    except CompileFailed as exc:
        if on_compile_error is None:
            raise DriverError(f"the shader does not compile: {exc.args[0]}") from None
        raise on_compile_error(exc.args[0]) from None
