"""Crash-safe file replacement and advisory locks for the run store.

Atomic replace: the new content is written to a temporary file *in the destination folder*
(``.tmp.<name>.<pid>.<random>``), flushed and fsynced, then renamed over the destination with
``os.replace``, and the folder itself is fsynced so that the rename is durable. A POSIX rename
within one file system is atomic, so a reader — or the file system after ``kill -9`` or a power
cut — sees either the old complete file or the new complete file, never a mixture. A crash can
only leave a stale temporary behind; readers ignore temporaries and the owner of the file
removes them when it next takes its lock (:func:`remove_temporaries`).

Locks are ``flock`` advisory locks on a small lock file; the kernel drops them when the holding
process dies, however it dies, so a killed run never leaves a stale lock. On systems without
``fcntl`` (Windows) locking is a no-op and a single writer per run is the user's responsibility.
Whether another process holds a lock is asked by taking it for a moment
(:meth:`FileLock.is_held_elsewhere`), so a non-blocking :meth:`FileLock.acquire` tries again
for up to :data:`PROBE_PATIENCE_S` before it reports the lock as held: a probe holds it for
microseconds, a holder for the length of its work.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import time
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

TEMP_PREFIX = ".tmp."


def temporary_name(target_name: str) -> str:
    """Name of a fresh temporary for ``target_name``: ``.tmp.<target>.<pid>.<random hex>``."""
    return f"{TEMP_PREFIX}{target_name}.{os.getpid()}.{secrets.token_hex(4)}"


def temporary_target(name: str) -> str | None:
    """The destination name a temporary was written for, or None if ``name`` is no temporary."""
    if not name.startswith(TEMP_PREFIX):
        return None
    parts = name[len(TEMP_PREFIX):].rsplit(".", 2)
    return parts[0] if len(parts) == 3 else None


def fsync_folder(folder: Path) -> None:
    """Make renames and new entries in ``folder`` durable (no-op where folders cannot be opened)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:  # pragma: no cover - Windows
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover - some file systems refuse fsync on folders
        pass
    finally:
        os.close(fd)


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Replace ``path`` by ``data`` atomically and durably (see the module docstring)."""
    path = Path(path)
    tmp = path.with_name(temporary_name(path.name))
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    fsync_folder(path.parent)


def remove_temporaries(folder: Path, targets=None) -> list[str]:
    """Delete stale temporaries in ``folder`` (only those for ``targets`` if given); return names.

    Call this only while holding the lock that protects the target files, so that no live
    writer's temporary is removed.
    """
    removed = []
    try:
        names = os.listdir(folder)
    except FileNotFoundError:
        return removed
    for name in names:
        target = temporary_target(name)
        if target is None or (targets is not None and target not in targets):
            continue
        with contextlib.suppress(FileNotFoundError):
            os.unlink(Path(folder) / name)
            removed.append(name)
    return removed


def set_aside(file: Path) -> Path:
    """Rename the damaged ``file`` to ``<name>.damaged-<n>`` beside it (the first ``n`` not
    taken; never deleted) and return the new path."""
    file = Path(file)
    n = 1
    while file.with_name(f"{file.name}.damaged-{n}").exists():
        n += 1
    target = file.with_name(f"{file.name}.damaged-{n}")
    os.replace(file, target)
    return target


#: How long a non-blocking acquire keeps trying (every ``PROBE_RETRY_S``) before the lock
#: counts as held by another process: longer than any probe of it holds it.
PROBE_PATIENCE_S, PROBE_RETRY_S = 0.1, 0.005


def locks_work() -> bool:
    """Whether this system has ``flock`` (not Windows): without it a lock is never held."""
    return fcntl is not None


class FileLock:
    """Exclusive advisory lock on ``path`` (created if missing), released on close or death."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def acquire(self, blocking: bool = False, patience: float = PROBE_PATIENCE_S) -> bool:
        """Take the lock; return False if another holder has it and ``blocking`` is False
        (after trying again for ``patience`` seconds: another process may only be asking
        whether it is held)."""
        if self._fd is not None:
            return True
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        if fcntl is not None:
            deadline = time.monotonic() + patience
            while True:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | (0 if blocking else fcntl.LOCK_NB))
                    break
                except BlockingIOError:
                    if time.monotonic() >= deadline:
                        os.close(fd)
                        return False
                    time.sleep(PROBE_RETRY_S)
        self._fd = fd
        return True

    def release(self) -> None:
        if self._fd is not None:
            fd, self._fd = self._fd, None
            os.close(fd)  # closing the descriptor drops the flock

    def is_held_elsewhere(self, patience: float = PROBE_PATIENCE_S) -> bool:
        """True if some other open lock (another process or object) holds ``path`` now.
        With ``patience=0`` one try: quick where a holder is alive, and a lock that is only
        being probed by another reader counts as held."""
        if self._fd is not None or fcntl is None or not self.path.exists():
            return False
        probe = FileLock(self.path)
        if probe.acquire(patience=patience):
            probe.release()
            return False
        return True

    def __del__(self):
        self.release()


@contextlib.contextmanager
def locked_update(folder: Path, name: str, lock_name: str):
    """Hold the lock file ``lock_name`` in ``folder`` (waiting for it) with the stale
    temporaries of the file ``name`` removed: the read-merge-write of a file that several
    processes add to (each reads the file inside, merges its part and writes it atomically)."""
    folder = Path(folder)
    lock = FileLock(folder / lock_name)
    lock.acquire(blocking=True)
    try:
        remove_temporaries(folder, {name})
        yield
    finally:
        lock.release()
