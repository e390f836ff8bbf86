"""Atomic file output: write to a temporary file in the target folder, then rename.

An interrupted run never leaves a half-written file behind: either the old file
(or none) or the complete new one is on disk.

Temporaries. :func:`atomic_path` creates its temporary file and registers it in
one step during which the Python handlers of SIGINT, SIGTERM and SIGHUP are
deferred, so that no ``KeyboardInterrupt`` lands between the two: a signal
raised inside the guarded block removes the temporary, and one handed over as
the creation step ends (before that block is entered) finds it registered, and
:func:`remove_temporaries` (the command line's exit path, and ``atexit``) removes
it. A writer killed outright (SIGKILL) leaves its temporary, which the next
writer of the same file removes (:func:`clean_stale`).
"""

from __future__ import annotations

import atexit
import contextlib
import glob
import io
import os
import signal
import tempfile
import threading
from pathlib import Path

__all__ = ["atomic_path", "clean_stale", "remove_temporaries", "write_bytes", "write_text", "save_npz",
           "save_figure"]

#: Temporaries of this process's unfinished writes.
_LIVE = set()
_HELD = {getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)}


@contextlib.contextmanager
def _signals_held():
    """Defer the Python handlers of SIGINT, SIGTERM and SIGHUP to the end of the block.

    Python runs signal handlers in the main thread, between two bytecodes: a
    handler that raises (``KeyboardInterrupt``) can land between any two lines.
    A thread-level signal mask would not keep it out (the kernel hands a
    process-wide signal to another thread, OpenBLAS's, and the handler still
    runs here), so the handlers are swapped for one that notes the signal, and
    the noted signals are handed to the real handlers when the block is left.
    Other threads are never interrupted by a Python handler and need nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    noted, old = [], {}
    for s in _HELD:
        handler = signal.getsignal(s)
        if callable(handler):  # SIG_DFL and SIG_IGN raise nothing here
            old[s] = signal.signal(s, lambda signum, frame: noted.append((signum, frame)))
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)
        for signum, frame in noted:
            old[signum](signum, frame)


def remove_temporaries() -> list[str]:
    """Remove the temporaries of this process's unfinished :func:`atomic_path` writes; return their paths."""
    removed = []
    for tmp in list(_LIVE):
        with contextlib.suppress(OSError):
            os.unlink(tmp)
            removed.append(tmp)
        _LIVE.discard(tmp)
    return removed


atexit.register(remove_temporaries)


def _mode() -> int:
    """0666 under the process umask (0644 with the usual 022), as ``open`` creates files."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def clean_stale(path) -> list[Path]:
    """Remove temporaries of ``path`` left by a killed writer (``.<name>.<pid>.*``, pid gone).

    Returns the removed paths. A temporary of a writer still running is kept.
    """
    path = Path(path)
    removed = []
    if not path.parent.is_dir():
        return removed
    for tmp in path.parent.glob(f".{glob.escape(path.name)}.*"):
        parts = tmp.name[len(path.name) + 2:].split(".", 1)
        if not parts[0].isdigit() or _pid_alive(int(parts[0])):
            continue
        with contextlib.suppress(OSError):
            tmp.unlink()
            removed.append(tmp)
    return removed


@contextlib.contextmanager
def atomic_path(path, suffix=None):
    """Yield a temporary path beside ``path``; rename it over ``path`` on success.

    The temporary file ``.<name>.<pid>.<random><suffix>`` keeps ``path``'s suffix
    (or ``suffix``) so that libraries choosing a format by extension (matplotlib)
    behave. On any exception (including KeyboardInterrupt) it is removed and
    ``path`` is left untouched; temporaries of earlier writers that were killed
    (SIGKILL leaves no chance to clean up) are removed first. The file is created
    with the usual permissions (0666 under the umask: 0644) and fsynced before the
    rename, so a crash leaves either the old or the complete new file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    clean_stale(path)
    with _signals_held():  # created and registered in one step (module docstring)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=suffix or path.suffix,
                                   dir=path.parent)
        _LIVE.add(tmp)
        try:
            os.fchmod(fd, _mode())
        finally:
            os.close(fd)
    try:
        yield Path(tmp)
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    finally:
        _LIVE.discard(tmp)


def write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text(path, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    return write_bytes(path, text.encode("utf-8"))


def save_npz(path, arrays: dict) -> bytes:
    """Write an uncompressed ``.npz`` atomically and deterministically; return its bytes.

    ``np.savez`` stamps zip entries with the current time; writing through an
    in-memory buffer with a fixed timestamp makes the same arrays give the same bytes.
    """
    import zipfile

    import numpy as np

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as zf:
        for name in sorted(arrays):
            arr_buf = io.BytesIO()
            np.lib.format.write_array(arr_buf, np.asanyarray(arrays[name]), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.external_attr = 0o644 << 16
            zf.writestr(info, arr_buf.getvalue())
    data = buf.getvalue()
    write_bytes(path, data)
    return data


#: PNG metadata without the matplotlib version (the same figure gives the same bytes).
PNG_METADATA = {"Software": None}


def figure_png(fig, dpi=110) -> bytes:
    """The PNG bytes :func:`save_figure` writes for ``fig`` at ``dpi``."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata=PNG_METADATA)
    return buf.getvalue()


def save_figure(fig, path, **kwargs) -> Path:
    """``fig.savefig`` atomically (PNG metadata without a timestamp)."""
    kwargs.setdefault("metadata", PNG_METADATA if str(path).endswith(".png") else None)
    if kwargs["metadata"] is None:
        kwargs.pop("metadata")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, **kwargs)
    return Path(path)
