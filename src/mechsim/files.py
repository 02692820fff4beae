"""The files mechsim writes: never through a symbolic link, never half-written.

Every output goes into a directory its caller chose (the root: a run's output directory, a
stream's directory, the folder of a saved result). The root must not itself be a link; it
is opened once (O_DIRECTORY | O_NOFOLLOW) and everything below it is made through that
descriptor, so a link planted or swapped in later, at the root's place or inside it, is
never followed: files are created with O_CREAT | O_EXCL | O_NOFOLLOW relative to it, and
put in place by renaming, which replaces a link rather than writing through it.

A file is written under a temporary name and renamed into place, so a reader sees the old
file or the whole new one. Writers that need a path (matplotlib, meshio, numpy, Pillow)
write into a private staging directory inside the root, reached through the root's
descriptor (/proc/self/fd on Linux); its files are renamed into the root only once the
writer has finished, and an interrupted writer leaves nothing (its staging directory is
removed, or, after a kill, on the next `OutputDirectory` of the same root).
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import shutil
import stat
from pathlib import Path

STAGING = ".mechsim-staging-"
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_DIRECTORY = getattr(os, "O_DIRECTORY", 0)


class UnsafePathError(ValueError):
    """An output path that is, or passes through, a symbolic link where mechsim writes."""


def _open_directory(name, dir_fd=None, shown="") -> int:
    """A descriptor of the directory `name` (relative to dir_fd), not following a link."""
    try:
        fd = os.open(name, os.O_RDONLY | _DIRECTORY | _NOFOLLOW, dir_fd=dir_fd)
    except OSError as exc:
        if exc.errno in (errno.ELOOP, errno.ENOTDIR):
            raise UnsafePathError(f"{shown or name} is a symbolic link or not a directory; "
                                  "mechsim writes only into real directories") from None
        raise
    if not stat.S_ISDIR(os.fstat(fd).st_mode):
        os.close(fd)
        raise UnsafePathError(f"{shown or name} is not a directory")
    return fd


class OutputDirectory:
    """A directory mechsim writes into (see the module docstring), created if missing
    (its parents too: they are the caller's choice), held open until `close`."""

    def __init__(self, path, create: bool = True):
        self.fd = None
        self.path = Path(path)
        if os.path.islink(self.path):
            raise UnsafePathError(f"{self.path} is a symbolic link; mechsim writes only into "
                                  "real directories: give the directory it points to")
        if create:
            self.path.mkdir(parents=True, exist_ok=True)
        self.fd = _open_directory(str(self.path), shown=str(self.path))
        self._clean_stale_staging()

    # --- the descriptor ----------------------------------------------------------------------
    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        try:
            self.close()
        except OSError:
            pass

    def _via(self, fd) -> Path:
        """A path that reaches the directory of `fd` through the descriptor itself."""
        proc = Path(f"/proc/self/fd/{fd}")
        return proc if proc.is_dir() else self.path

    # --- entries -----------------------------------------------------------------------------
    def subdirectory(self, name: str) -> "OutputDirectory":
        """The directory `name` inside this one (created), opened without following links."""
        _check_name(name)
        with contextlib.suppress(FileExistsError):
            os.mkdir(name, 0o777, dir_fd=self.fd)
        sub = OutputDirectory.__new__(OutputDirectory)
        sub.path = self.path / name
        sub.fd = _open_directory(name, self.fd, shown=str(sub.path))
        return sub

    def exists(self, name: str) -> bool:
        try:
            os.stat(name, dir_fd=self.fd, follow_symlinks=False)
            return True
        except FileNotFoundError:
            return False

    def names(self) -> list[str]:
        return sorted(os.listdir(self.fd))

    def remove(self, name: str) -> None:
        """Unlink `name` (a file or a link, never what a link points to) if it is there."""
        _check_name(name)
        with contextlib.suppress(FileNotFoundError):
            os.unlink(name, dir_fd=self.fd)

    def new_file(self, name: str):
        """A new, empty binary file `name` open for writing (any entry of that name is
        unlinked first: a memory map of an earlier file keeps its own data)."""
        _check_name(name)
        self.remove(name)
        fd = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o666,
                     dir_fd=self.fd)
        return os.fdopen(fd, "wb")

    def open_read(self, name: str):
        """`name` open for reading as a binary file, not through a link."""
        _check_name(name)
        return os.fdopen(os.open(name, os.O_RDONLY | _NOFOLLOW, dir_fd=self.fd), "rb")

    def size(self, name: str) -> int:
        """The size in bytes of the file `name` (FileNotFoundError where there is none)."""
        return os.stat(name, dir_fd=self.fd, follow_symlinks=False).st_size

    def map(self, name: str, shape):
        """The float64 file `name` as a read-only memory map of `shape` (row-major)."""
        import numpy as np
        with self.open_read(name) as f:
            return np.memmap(f, dtype=np.float64, mode="r", shape=tuple(shape))

    def write_bytes(self, name: str, data: bytes) -> Path:
        """Write `data` to `name` atomically (a temporary name, renamed into place)."""
        _check_name(name)
        tmp = f".{name}.{secrets.token_hex(4)}.tmp"
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o666,
                     dir_fd=self.fd)
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            os.replace(tmp, name, src_dir_fd=self.fd, dst_dir_fd=self.fd)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp, dir_fd=self.fd)
            raise
        return self.path / name

    def write_text(self, name: str, text: str) -> Path:
        return self.write_bytes(name, text.encode("utf-8"))

    @contextlib.contextmanager
    def staged(self, shared: bool = False):
        """A private directory for writers that need paths (a Path reaching it through its
        descriptor; `shared`: its plain path, for a writer in another process, which cannot
        use this one's descriptors); on leaving the block every file in it is renamed into
        this directory, and the staging directory removed. If the block raises (Ctrl-C
        included), nothing is renamed and the staging directory goes."""
        name = f"{STAGING}{os.getpid()}-{secrets.token_hex(4)}"
        os.mkdir(name, 0o700, dir_fd=self.fd)
        try:
            fd = _open_directory(name, self.fd)
        except BaseException:
            self._remove_tree(name)
            raise
        try:
            yield self.path / name if shared else self._via(fd)
            for entry in sorted(os.listdir(fd)):
                os.replace(entry, entry, src_dir_fd=fd, dst_dir_fd=self.fd)
        finally:
            os.close(fd)
            self._remove_tree(name)

    def _remove_tree(self, name) -> None:
        shutil.rmtree(name, ignore_errors=True, dir_fd=self.fd)     # links not followed

    def _clean_stale_staging(self) -> None:
        """Remove the staging directories of processes that are gone (killed mid-write)."""
        for name in os.listdir(self.fd):
            if not name.startswith(STAGING):
                continue
            pid = name[len(STAGING):].split("-", 1)[0]
            if pid.isdigit() and not alive(int(pid)):
                self._remove_tree(name)


def alive(pid: int) -> bool:
    """Is the process `pid` running (or not ours to ask)?"""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def _check_name(name: str) -> None:
    if not name or name in (".", "..") or "/" in name or "\0" in name:
        raise UnsafePathError(f"{name!r} is not a file name inside an output directory")


def output_file(path) -> tuple[OutputDirectory, str]:
    """(the directory of `path`, held open; the file's name) for writing one file."""
    path = Path(path)
    return OutputDirectory(path.parent), path.name


def written(path, write, shared: bool = False) -> Path:
    """Write the output `path` through a staging directory in its folder: `write(p)` gets
    a path of the same name in it (and may write more files beside it, which go too); they
    are renamed into place once it returns, and nothing is if it raises. Returns `path`."""
    path = Path(path)
    with OutputDirectory(path.parent) as directory, directory.staged(shared) as tmp:
        write(tmp / path.name)
    return path


def save_figure(fig, path, dpi=120) -> Path:
    """`fig.savefig(path)` through `written`."""
    return written(path, lambda p: fig.savefig(p, dpi=dpi))
