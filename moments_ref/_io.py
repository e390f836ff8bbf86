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
writer of the same file removes (:func:`clean_stale`). A temporary's name is the
command's own, ``.<name>.<pid>.mrtmp<8 random>`` with the target's suffix: a
user's file beside it (``.results.csv.20240101.bak``) never matches it.

What a command writes is its own (:func:`atomic_path` refuses to replace anything
but a regular file: a device, FIFO, link or folder in the way is an
:class:`~moments_ref.InputError`). A target the user names (``--json PATH``) goes
through :func:`write_output`: a new path or a regular file is written atomically
(a link to a regular file: the file it names, the link kept), a character
device, FIFO or pipe (``/dev/stdout``, ``/dev/null``, ``>(cat)``) is written
through as a stream and never replaced, anything else is refused.
:func:`folder_lock` keeps a second writer out of a folder and
:func:`marked_incomplete` marks a folder while a set of files is rewritten.
"""

from __future__ import annotations

import atexit
import contextlib
import errno
import glob
import io
import os
import re
import signal
import stat
import tempfile
import time
import threading
from pathlib import Path

__all__ = ["atomic_path", "clean_stale", "remove_temporaries", "write_bytes", "write_text", "save_npz",
           "save_figure", "tight_layout", "write_files", "write_output", "check_output", "check_own", "read_own",
           "folder_lock", "marked_incomplete", "INCOMPLETE"]

#: The tag of a temporary's name (``.<name>.<pid>.mrtmp<8 random><suffix>``).
_TAG = "mrtmp"
#: The marker of a folder whose set of files is being (or was not completely) rewritten.
INCOMPLETE = "INCOMPLETE"

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
    own = re.compile(r"(\d+)\." + _TAG + r"[a-z0-9_]{8}(\.[A-Za-z0-9]{1,8})?")
    for tmp in path.parent.glob(f".{glob.escape(path.name)}.*"):
        m = own.fullmatch(tmp.name[len(path.name) + 2:])
        if m is None or _pid_alive(int(m.group(1))) or not tmp.is_file() or tmp.is_symlink():
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
    ``path`` is left untouched (and a ``path`` that is not a regular file is
    refused before anything is written: :func:`check_own`); temporaries of earlier writers that were killed
    (SIGKILL leaves no chance to clean up) are removed first. The file is created
    with the usual permissions (0666 under the umask: 0644) and fsynced before the
    rename, so a crash leaves either the old or the complete new file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    check_own(path)
    clean_stale(path)
    with _signals_held():  # created and registered in one step (module docstring)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.{_TAG}", suffix=suffix or path.suffix,
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


def write_files(folder, blobs: dict) -> list:
    """Write ``{file name: bytes or text}`` into ``folder``, all or none; return the paths.

    Every file goes to its temporary first (written and fsynced); only when all
    of them are written are they renamed over their targets. A failure while
    writing (a full disk, a FIFO in the way) removes every temporary and leaves
    the folder as it was.
    """
    folder = Path(folder)
    with contextlib.ExitStack() as stack:
        for name, data in blobs.items():
            tmp = stack.enter_context(atomic_path(folder / name))
            tmp.write_bytes(data.encode("utf-8") if isinstance(data, str) else data)
    return [folder / name for name in blobs]


def write_text(path, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    return write_bytes(path, text.encode("utf-8"))


def write_between(path, markers, block: str) -> Path:
    """Replace the text between the two ``markers`` of the file ``path`` by ``block`` (atomically).

    The generated blocks of the docs (a table written by the command that measures or lists it)
    are kept between such markers; a file without exactly one of each, in order, is refused.
    """
    from ._arrays import InputError

    path = Path(path)
    text = path.read_text(encoding="utf-8")
    begin, end = markers
    if text.count(begin) != 1 or text.count(end) != 1 or text.index(begin) > text.index(end):
        raise InputError(f"{path}: expected one {begin!r} before one {end!r}")
    head, rest = text.split(begin, 1)
    return write_text(path, head + begin + block + end + rest.split(end, 1)[1])


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


def _without_placeholder_layout(fig):
    """Drop the inert layout engine that ``fig.tight_layout()`` leaves behind, so that ``savefig`` draws once.

    ``Figure.tight_layout`` lays the figure out once and then sets a
    ``PlaceHolderLayoutEngine``, which does nothing; but ``savefig`` sees a layout
    engine and draws the whole figure a first time (with rendering disabled)
    before drawing it into the file. Without the placeholder the file's bytes are
    the same (tested) and saving takes two thirds to four fifths of the time. A figure with
    a working engine (``constrained_layout=True``) keeps it.
    """
    from matplotlib import layout_engine

    placeholder = getattr(layout_engine, "PlaceHolderLayoutEngine", None)  # matplotlib >= 3.6.1
    if placeholder is not None and isinstance(fig.get_layout_engine(), placeholder):
        fig.set_layout_engine(None)


def tight_layout(fig, rect=None):
    """``fig.tight_layout(rect=rect)`` measuring each Axes' tight box once, not once per pass.

    With a ``rect`` matplotlib's tight layout runs its margin computation twice
    (the second time with the margins the first found folded into ``rect``), and
    each run measures the tight box of every Axes again (its title, tick labels
    and texts laid out by the renderer), although nothing changed in between:
    the figure is only adjusted after the second run. Here each Axes' box is
    measured on the first request and handed back on the second (the same
    ``Bbox``, so the same subplot parameters and pixels; tested against
    ``fig.tight_layout``); the memo lives only during the call.
    """
    axes = list(fig.axes)
    for ax in axes:
        ax.get_tightbbox = _measured_once(ax.get_tightbbox)  # an instance attribute over the method
    try:
        fig.tight_layout(rect=rect)
    finally:
        for ax in axes:
            ax.__dict__.pop("get_tightbbox", None)


def _measured_once(get_tightbbox):
    """``get_tightbbox`` answering a repeated request (same renderer and arguments) from its first answer."""
    memo = {}

    def once(renderer=None, *args, **kwargs):
        key = (id(renderer), args, tuple(sorted(kwargs.items())))
        if key not in memo:
            memo[key] = (renderer, get_tightbbox(renderer, *args, **kwargs))  # keeps the renderer (its id) alive
        return memo[key][1]

    return once


#: zlib level of the report's PNG files (:func:`figure_png`'s ``compress_level``). Pillow's default, 6,
#: took 0.75–0.80 s of CPU to encode the default report's 26 figures (3.04 MB); level 2 took 0.47–0.50 s
#: for 3.22 MB (level 1: the same time, 3.32 MB; level 3: 0.49–0.66 s, 3.14 MB). The pixels are the same
#: at every level (PNG is lossless); only the bytes differ.
REPORT_PNG_LEVEL = 2


def figure_png(fig, dpi=110, compress_level=None) -> bytes:
    """The PNG bytes :func:`save_figure` writes for ``fig`` at ``dpi``.

    ``compress_level``: zlib's level 0–9 for Pillow's PNG encoder (the same pixels,
    larger and quicker files at low levels; :data:`REPORT_PNG_LEVEL`); None: Pillow's
    default, the bytes of ``fig.savefig``.
    """
    _without_placeholder_layout(fig)
    buf = io.BytesIO()
    extra = {} if compress_level is None else {"pil_kwargs": {"compress_level": int(compress_level)}}
    fig.savefig(buf, format="png", dpi=dpi, metadata=PNG_METADATA, **extra)
    return buf.getvalue()


def save_figure(fig, path, **kwargs) -> Path:
    """``fig.savefig`` atomically (PNG metadata without a timestamp)."""
    kwargs.setdefault("metadata", PNG_METADATA if str(path).endswith(".png") else None)
    if kwargs["metadata"] is None:
        kwargs.pop("metadata")
    _without_placeholder_layout(fig)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, **kwargs)
    return Path(path)


def _what(st) -> str:
    m = st.st_mode
    return ("a folder" if stat.S_ISDIR(m) else "a link" if stat.S_ISLNK(m) else "a FIFO" if stat.S_ISFIFO(m) else
            "a character device" if stat.S_ISCHR(m) else "a block device" if stat.S_ISBLK(m) else
            "a socket" if stat.S_ISSOCK(m) else "not a regular file")


def check_own(path, what=None) -> None:
    """Refuse a ``path`` a command would replace that is there and is not a regular file.

    A device, FIFO, socket or link where the command writes one of its own files
    (``bench.md``, ``manifest.json``) is the user's, never replaced nor read:
    :class:`~moments_ref.InputError` naming it. (A folder there is left to the
    rename, which cannot replace it: its ``OSError`` names it.)
    """
    from ._arrays import InputError

    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    if not stat.S_ISREG(st.st_mode) and not stat.S_ISDIR(st.st_mode):  # a folder: the rename fails (EISDIR)
        raise InputError(f"{what or 'out'}: {path} is {_what(st)}, not a regular file; refusing to replace it "
                         "(remove it or choose another folder)")


def read_own(path, limit, what=None):
    """The bytes of the command's own earlier file ``path`` (a regular file of at most ``limit`` bytes), or None.

    None when it is not there; a device, FIFO or link is refused (:func:`check_own`),
    so that a FIFO never blocks and ``/dev/zero`` is never read.
    """
    check_own(path, what)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except FileNotFoundError:
        return None
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):  # swapped in between
            return None
        data = f.read(limit + 1)
    return None if len(data) > limit else data


def _output_kind(path, what):
    """``("file", path to write atomically)`` or ``("stream", path)`` for a user-named output; refuses the rest."""
    from ._arrays import InputError

    path = Path(path)
    try:
        lst = os.lstat(path)
    except FileNotFoundError:
        return "file", path
    try:
        st = os.stat(path)
    except OSError:  # a link to a file not there yet: created, as the shell's ``>`` does, if its folder is
        target = Path(os.path.realpath(path))
        if not target.parent.is_dir() or str(target).startswith(("/proc/", "/dev/")):
            raise InputError(f"{what}: {path} is a link to nothing (no folder {target.parent}); refusing to write "
                             "through it") from None
        return "file", target
    linked = stat.S_ISLNK(lst.st_mode)
    if stat.S_ISCHR(st.st_mode) or stat.S_ISFIFO(st.st_mode):
        return "stream", path
    if stat.S_ISREG(st.st_mode):
        system = ("/proc/", "/dev/")  # never renamed over: /dev/stdout redirected to a file appends to it
        if str(os.path.realpath(path)).startswith(system) or os.path.abspath(path).startswith(system) or (
                linked and os.readlink(path).startswith(system)):
            return "stream", path
        return "file", Path(os.path.realpath(path)) if linked else path
    raise InputError(f"{what}: {path} is {_what(st)}; expected a file, a new path, a character device or a FIFO")


def check_output(path, what="--json") -> None:
    """Refuse, before any work, a user-named output that :func:`write_output` would refuse (a folder, a
    socket, a block device, a link to nothing, a folder that is not there); nothing is opened."""
    from ._arrays import InputError

    kind, target = _output_kind(path, what)
    if kind == "file" and not Path(target).parent.is_dir():
        raise InputError(f"{what}: the folder of {path} does not exist")


def _open_stream(path, what, wait=10.0):
    """A write descriptor of the device, FIFO or pipe ``path``; a FIFO without a reader for ``wait`` s is refused."""
    from ._arrays import InputError

    flags = os.O_WRONLY | os.O_APPEND | os.O_NOCTTY | os.O_NONBLOCK
    end = time.monotonic() + wait
    while True:
        try:
            fd = os.open(path, flags)
            break
        except OSError as exc:
            if exc.errno != errno.ENXIO:
                raise
            if not stat.S_ISFIFO(os.stat(path).st_mode):  # a device that is not there (/dev/tty without a terminal)
                raise InputError(f"{what}: cannot write to {path}: no such device") from None
            if time.monotonic() > end:
                raise InputError(f"{what}: the FIFO {path} has no reader (waited {wait:g} s)") from None
            time.sleep(0.05)
    os.set_blocking(fd, True)
    return fd


def write_output(path, data, what="--json") -> Path:
    """Write ``data`` (bytes or text, UTF-8) to the output ``path`` a user named (``--json``, ``--out`` files).

    A new path or a regular file: atomically (:func:`atomic_path`; a link to a
    regular file writes that file and keeps the link). A character device, FIFO
    or pipe (``/dev/stdout``, ``/dev/null``, ``/dev/full``, ``>(cat > j.json)``):
    written through as a stream, never replaced (a FIFO nobody reads for 10 s is
    refused). Anything else (a folder, a socket, a block device, a dangling link):
    :class:`~moments_ref.InputError`. A stream that fails (``/dev/full``) raises its
    ``OSError``, which the command line turns into one line and exit 2.
    """
    import sys

    data = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    kind, target = _output_kind(path, what)
    if kind == "file":
        return write_bytes(target, data)
    for s in (sys.stdout, sys.stderr):  # what the command printed comes first on a shared stream
        with contextlib.suppress(Exception):
            s.flush()
    from ._arrays import InputError

    try:
        fd = _open_stream(target, what)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
        finally:
            os.close(fd)
    except OSError as exc:
        raise InputError(f"{what}: could not write to {path} ({exc.strerror or exc})") from None
    return Path(path)


@contextlib.contextmanager
def folder_lock(folder, command="moments-ref"):
    """Hold ``folder``'s write lock (``flock`` on the folder itself) for the block; a second writer is refused.

    No lock file is made: nothing is left behind, also by a writer killed outright
    (the kernel drops the lock with the process). :class:`~moments_ref.InputError`
    if another process holds it.
    """
    import fcntl

    from ._arrays import InputError

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError(f"out: another process is writing into {folder} (another {command} holds its lock); "
                             "wait for it or choose another folder") from None
        yield folder
    finally:
        os.close(fd)


@contextlib.contextmanager
def marked_incomplete(folder, text):
    """Keep the marker :data:`INCOMPLETE` (holding ``text``) in ``folder`` while the block rewrites its files.

    Written before the first file and removed after the last: a rewrite that
    fails, is interrupted or killed leaves the folder marked, and the readers of
    the folder name it as incomplete.
    """
    marker = Path(folder) / INCOMPLETE
    old = read_own(marker, 1 << 16, "out")
    if old is not None and b"not completely written" not in old:  # the user's own file of that name
        from ._arrays import InputError

        raise InputError(f"out: {marker} is not this command's marker; refusing to replace it")
    write_text(marker, text)
    yield marker
    marker.unlink()
