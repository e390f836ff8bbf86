"""Errors shared by the conformance drivers (a leaf module, so that the driver modules import no cycle)."""

from __future__ import annotations

__all__ = ["ContextError", "LocalCompileError"]


class ContextError(RuntimeError):
    """No driver (OpenGL 4.3 compute context, Vulkan adapter or compiler); ``str(exc)`` says why."""


class LocalCompileError(Exception):
    """A driver's compiler refused a shader; ``str(exc)`` is its log."""
