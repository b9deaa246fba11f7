"""The recorder's log file (:mod:`hound_id.dyno.acquire.recorder`): the canonical CSV opened for appending under a lock
so two recorders never share it, refused when it already holds data, and its JSON sidecar."""

from __future__ import annotations

import fcntl
import json
import os
import stat
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from hound_id import io
from hound_id.errors import OutputError


def sidecar_path(out: Path) -> Path:
    """``run.csv`` -> ``run.csv.meta.json``."""
    return out.with_name(out.name + ".meta.json")


class CsvLog:
    """The CSV file of a run: locked against a second recorder, written in whole rows only, LF line endings.

    A new file (or an empty one) is opened without truncation, locked with ``flock`` (a second recorder on the
    same file is refused with the PID of the first) and given its header. A log already at ``path`` is refused
    unless ``overwrite``; then it is locked, and the run writes to a hidden file beside it (:attr:`writing`)
    that replaces it (and its sidecar) with the first rows: until then it is untouched. The locks are held
    until :meth:`close`.

    Raises:
        OutputError: The file cannot be created or written, another recorder holds it, or a log is already
            there and ``overwrite`` was not given.
    """

    def __init__(self, path: Path, columns: Sequence[str], overwrite: bool = False) -> None:
        io.check_output(path, (".csv",), "log")
        check_free(path)  # another recorder's file: say so first
        check_existing(path, overwrite)
        self.path = path
        self.columns = ["time", *columns]
        self.rows = 0
        """Whole rows in the file."""
        self._old_fd = -1
        self._size = 0
        self.writing = path
        """The file being written: ``path``, or the hidden file that replaces it with the first rows."""
        self.created = not path.exists()
        """Whether the run made the file (nothing was at ``path``)."""
        if _holds_data(path):
            self._old_fd = _open_locked(path, os.O_RDONLY)  # the old log: no second recorder, kept till replaced
            try:
                fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".recording", dir=path.parent)
                os.fchmod(fd, 0o666 & ~io.umask())
            except OSError as err:
                self.close()
                raise OutputError(
                    f"{path.parent}: cannot write ({err.strerror or err}); choose another --out", path=str(path)
                ) from err
            self.writing = Path(name)
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # a file only this process knows: never held
        else:
            fd = _open_locked(path, os.O_WRONLY | os.O_CREAT)
        self._fd = fd
        try:
            if stat.S_ISREG(os.fstat(fd).st_mode):
                os.ftruncate(fd, 0)
            # columns are checked names (no commas or quotes): a plain join is valid CSV
            self._write(",".join(self.columns) + "\n", 1)
        except OSError as err:
            self.close()
            raise OutputError(
                f"{path}: cannot write the header ({err.strerror or err}); free space or choose another --out",
                path=str(path),
            ) from err
        self.rows = 0

    @property
    def replaced(self) -> bool:
        """Whether the file at :attr:`path` is this run's (False while an old log waits for the first rows)."""
        return self.writing == self.path

    def append(self, rows: Sequence[str]) -> None:
        """Write whole rows (each ending in a newline).

        Raises:
            OSError: The write failed (disk full, file size limit); the file was cut back to its last
                whole row and :attr:`rows` counts the rows in it.
        """
        if rows:
            try:
                self._write("".join(rows), len(rows))
            finally:  # rows in hand, even when a write failed part-way: they replace the old log
                if self.rows and not self.replaced:
                    self._replace_old()

    def _replace_old(self) -> None:
        """Move the hidden file (which now holds rows) onto the old log, and drop the old log's sidecar with
        it: the next sidecar write describes this run."""
        hidden = self.writing
        os.replace(hidden, self.path)
        self.writing = self.path
        for stale in (sidecar_path(hidden), sidecar_path(self.path)):
            stale.unlink(missing_ok=True)
        self._release_old()

    def _release_old(self) -> None:
        """Close the old log (and release its lock), once."""
        old, self._old_fd = self._old_fd, -1
        if old >= 0:
            os.close(old)

    def _write(self, text: str, n: int) -> None:
        data = text.encode("utf-8")
        view = memoryview(data)
        done = 0
        try:
            while done < len(data):
                done += os.write(self._fd, view[done:])
        except OSError:
            whole = data.rfind(b"\n", 0, done) + 1  # bytes up to the last complete row
            self.rows += data.count(b"\n", 0, whole)
            self._size += whole
            if done > whole:  # cut the half row off
                try:
                    os.ftruncate(self._fd, self._size)
                    os.lseek(self._fd, self._size, os.SEEK_SET)
                except OSError:
                    pass
            raise
        self.rows += n
        self._size += len(data)

    def sync(self) -> None:
        """Make the rows durable (fsync)."""
        os.fsync(self._fd)

    def close(self) -> None:
        """Close the file and release the locks (idempotent); a hidden file that never replaced the old log is
        removed with its sidecar, so the old log stays as it was."""
        fd, self._fd = getattr(self, "_fd", -1), -1
        if fd >= 0:
            os.close(fd)
        if not self.replaced:
            for leftover in (self.writing, sidecar_path(self.writing)):
                leftover.unlink(missing_ok=True)
        self._release_old()


def _holds_data(path: Path) -> bool:
    """Whether ``path`` is a regular file with something in it (an empty file is not a log)."""
    try:
        info = os.stat(path)
    except OSError:
        return False
    return stat.S_ISREG(info.st_mode) and info.st_size > 0


def _open_locked(path: Path, flags: int) -> int:
    """``path`` opened with ``flags`` and locked (flock, not blocking)."""
    try:
        fd = os.open(path, flags | os.O_CLOEXEC, 0o666)
    except OSError as err:
        message = f"{path}: cannot write ({err.strerror or err}); choose another --out"
        raise OutputError(message, path=str(path)) from err
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError as err:
        os.close(fd)
        raise _locked(path) from err
    except OSError as err:
        os.close(fd)
        raise OutputError(
            f"{path}: cannot lock the file ({err.strerror or err}); record to a local disk", path=str(path)
        ) from err
    return fd


def check_existing(path: Path, overwrite: bool, inputs: Sequence[Path] = ()) -> None:
    """Refuse a log, or a sidecar, already at ``path`` unless ``overwrite``, and a sidecar path that is not a
    regular file or is one of ``inputs`` (before connecting to the rig).

    Raises:
        OutputError: ``path`` or its sidecar holds data and ``overwrite`` is False; the sidecar path is a FIFO, a
            folder, a device or an input.
    """
    side = sidecar_path(path)
    io.check_output(side, (".json",), "sidecar", inputs)  # a FIFO, a folder or an input there: refused
    for target, what in ((path, "a recorded log?"), (side, "a recorded log's metadata?")):
        if not overwrite and _holds_data(target):
            size = os.stat(target).st_size
            raise OutputError(
                f"{target}: already holds {size:,} bytes ({what}); choose another --out, or pass --overwrite to "
                "replace it once the first sample is in (it is kept if none comes)",
                path=str(target),
            )


def check_free(path: Path) -> None:
    """Refuse at once an output another recorder is writing (before connecting to the rig).

    A probe: the lock is taken and released; :class:`CsvLog` takes it for the run.

    Raises:
        OutputError: Another recorder holds the file; the message names its PID when known.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return  # no file yet (or unreadable): CsvLog reports what is wrong
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError as err:
        raise _locked(path) from err
    except OSError:
        pass
    finally:
        os.close(fd)


def _locked(path: Path) -> OutputError:
    pid = _recorder_pid(sidecar_path(path))
    who = f"another recorder (PID {pid})" if pid is not None else "another recorder"
    return OutputError(
        f"{path}: {who} is writing this file; stop it first or choose another --out", path=str(path), pid=pid
    )


def _recorder_pid(side: Path) -> int | None:
    """The PID written in a running recorder's sidecar, if it is there."""
    try:
        pid = json.loads(side.read_text(encoding="utf-8")).get("pid")
    except (OSError, ValueError, AttributeError):
        return None
    return pid if isinstance(pid, int) and not isinstance(pid, bool) else None


def save_sidecar(path: Path, data: Mapping[str, Any]) -> None:
    """Atomic rewrite; on a full disk (no room for the temporary file) overwrite the old sidecar in place.

    Raises:
        OSError: Neither worked.
    """
    try:
        io.write_json(path, data)
    except OSError:
        text = (json.dumps(data, indent=2) + "\n").encode("utf-8")
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_CLOEXEC, 0o666)
        try:  # reuses the old file's blocks, so it fits when the new text is not much longer
            os.pwrite(fd, text, 0)
            os.ftruncate(fd, len(text))
        finally:
            os.close(fd)
