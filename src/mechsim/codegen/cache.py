"""On-disk cache of generated model modules and their compiled libraries, keyed by a hash of
the model's structure.

The cache directory is `$MECHSIM_CACHE_DIR` if set, else `$XDG_CACHE_HOME/mechsim` or
`~/.cache/mechsim`. Every entry (a generated module, a shared library) is written
atomically (temporary file, then rename) with a digest beside it (`<file>.sha256`: its
SHA-256 and its name), written when it was built; before an entry is imported or loaded it
is read back and checked against that digest, so a truncated, zero-byte, foreign or edited
file is rebuilt instead of crashing the process (a truncated library is a SIGBUS) or giving
another model's numbers. A module is compiled from the bytes that were checked, not read
again.

A cache directory that other users can write to (group or world writable, or owned by
someone else) is not trusted: mechsim warns once and keeps this process's entries in a
private temporary directory instead. So is a directory it cannot write. This module must not
import sympy.
"""

from __future__ import annotations

import atexit
import hashlib
import json
import os
import shutil
import stat
import sys
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np

from ..linalg.sparse import template, with_data

# Bump when the generated code changes meaning, so stale cache entries are not used.
CODEGEN_VERSION = 17          # 17: small models' C twins of (Φ, Φ_q) and (Φ_q, γ) for the engine


def cache_dir() -> Path:
    """The configured cache directory (it may not exist yet, nor be trusted; see `store`)."""
    env = os.environ.get("MECHSIM_CACHE_DIR")
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "mechsim"


def structure_key(structure) -> str:
    """A stable hash of a JSON-serialisable structure description."""
    text = json.dumps({"codegen": CODEGEN_VERSION, "structure": structure}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def env_flag(name: str) -> bool:
    """An environment switch: set to anything but "", "0", "false", "no" or "off"."""
    return os.environ.get(name, "").strip().lower() not in ("", "0", "false", "no", "off")


_warned: set = set()


def warn_once(key, message: str) -> None:
    """A UserWarning the first time `key` is seen in this process."""
    if key not in _warned:
        _warned.add(key)
        warnings.warn(message, stacklevel=3)


def _private(st: os.stat_result) -> bool:
    """Owned by this user and writable by nobody else."""
    if not hasattr(os, "getuid"):
        return True
    return st.st_uid == os.getuid() and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


_fallback: dict[str, Path] = {}


def store() -> Path:
    """The directory this process keeps its entries in: the configured one where it is
    private to this user and writable (created, mode 0700, if missing), else a private
    temporary directory removed at exit, with a warning saying why."""
    configured = cache_dir()
    try:
        configured.mkdir(mode=0o700, parents=True, exist_ok=True)
        st = configured.stat()
        problem = None
        if not stat.S_ISDIR(st.st_mode):
            problem = "is not a directory"
        elif not _private(st):
            problem = "is writable by other users (or owned by another user)"
        elif not os.access(configured, os.W_OK | os.X_OK):
            problem = "is not writable"
    except OSError as exc:
        problem = f"cannot be used ({exc.strerror or exc})"
    if problem is None:
        return configured
    key = str(configured)
    if key not in _fallback:
        tmp = Path(tempfile.mkdtemp(prefix="mechsim-cache-"))
        atexit.register(shutil.rmtree, tmp, ignore_errors=True)
        _fallback[key] = tmp
        warn_once(("store", key), f"mechsim: the model cache {configured} {problem}; models "
                  f"are built for this process only (in {tmp})")
    return _fallback[key]


# --- verified entries --------------------------------------------------------------------------
def _digest_path(path: Path) -> Path:
    return path.with_name(path.name + ".sha256")


def write_entry(path: Path, data: bytes) -> None:
    """Write `data` to `path` and its digest beside it, each atomically."""
    _atomic_write(path, data)
    record = f"{hashlib.sha256(data).hexdigest()}  {path.name}\n".encode()
    _atomic_write(_digest_path(path), record)


def _atomic_write(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def adopt(path: Path) -> None:
    """Write the digest of a file that is in place already (a library the compiler wrote
    into `path` by rename)."""
    data = path.read_bytes()
    _atomic_write(_digest_path(path), f"{hashlib.sha256(data).hexdigest()}  "
                                      f"{path.name}\n".encode())


def read_verified(path: Path) -> bytes | None:
    """The bytes of the entry at `path` if it matches the digest written when it was built
    and no other user could have written it; None otherwise (missing, truncated, foreign,
    edited: the caller rebuilds it)."""
    try:
        with open(path, "rb") as f:
            st = os.fstat(f.fileno())
            data = f.read()
        record = _digest_path(path).read_text().split()
        st_digest = _digest_path(path).stat()
    except (OSError, UnicodeDecodeError):
        return None
    if not (_private(st) and _private(st_digest)) or len(record) != 2:
        return None
    digest, name = record
    if name != path.name or digest != hashlib.sha256(data).hexdigest():
        return None
    return data


def verified_file(path: Path) -> bool:
    """Whether the entry at `path` passes `read_verified` (for files loaded by path)."""
    return read_verified(path) is not None


# --- generated modules -------------------------------------------------------------------------
def _module(name: str, source: str, path: Path | None) -> ModuleType:
    module = ModuleType(name)
    module.__file__ = None if path is None else str(path)
    code = compile(source, str(path) if path else f"<mechsim model {name}>", "exec")
    exec(code, module.__dict__)
    sparse_forms(module)
    return module


def sparse_forms(module) -> None:
    """Give a generated module whose Φ_q comes also as its non-zero entries (`phi_q_nz`:
    a model of `compiled.CSR_MIN_COORDINATES` coordinates or more) the forms a long
    chain's solvers take, Φ_q a CSR array of its pattern (`mechsim.linalg.sparse`):
    `phi_q_csr`, `position_terms_csr` and `dynamics_terms_csr`, as the assembled model
    has them. They call the module's functions as it has them at the call (its C twins
    once `attach`ed)."""
    if not hasattr(module, "phi_q_nz"):
        return
    rows = np.asarray(module.JACOBIAN_ROWS, dtype=np.intp)
    pattern = template(np.asarray(module.JACOBIAN_COLS, np.intp),
                       np.searchsorted(rows, np.arange(module.M + 1)), (module.M, module.N))

    def phi_q_csr(q, t, p):
        return with_data(pattern, module.phi_q_nz(q, t, p))

    def position_terms_csr(q, t, p):
        phi, data = module.position_terms_nz(q, t, p)
        return phi, with_data(pattern, data)

    def dynamics_terms_csr(q, v, t, p):
        data, gamma = module.dynamics_terms_nz(q, v, t, p)
        return with_data(pattern, data), gamma

    module.phi_q_csr, module.position_terms_csr = phi_q_csr, position_terms_csr
    module.dynamics_terms_csr = dynamics_terms_csr


_loaded: dict[str, ModuleType] = {}


def _entry(structure) -> tuple[str, str, Path]:
    """(key, module name, cache path) of a structure's module."""
    key = structure_key(structure)
    name = f"mechsim_model_{key}"
    return key, name, store() / f"{name}.py"


def cached_model(structure) -> ModuleType | None:
    """The module of `structure` if this process or the disk cache has it (a damaged disk
    entry is said in a warning and treated as missing); None otherwise. Never builds."""
    from .compiled import attach

    key, name, path = _entry(structure)
    if key in _loaded:
        return _loaded[key]
    data = read_verified(path)
    if data is None:
        if path.exists():
            warnings.warn(f"mechsim: cache entry {path} does not match its digest; "
                          "rebuilding it")
        return None
    try:
        module = _module(name, data.decode(), path)
        if getattr(module, "KEY", None) != key:
            raise ImportError(f"it holds the model {getattr(module, 'KEY', None)!r}")
    except Exception as exc:  # a damaged entry is rebuilt, never fatal
        warnings.warn(f"mechsim: ignoring unreadable cache entry {path}: {exc}")
        return None
    attach(module, path)
    _loaded[key] = module
    return module


def load_model(structure, build: Callable[[], str]) -> tuple[ModuleType, bool]:
    """Return (module, from_cache). `build()` produces the module source on a miss (or where
    the cached entry fails its digest, or does not import: then it is rebuilt with a
    warning)."""
    from .compiled import attach

    module = cached_model(structure)
    if module is not None:
        return module, True
    key, name, path = _entry(structure)
    source = build()
    try:
        write_entry(path, source.encode())
        module = _module(name, source, path)
    except OSError as exc:
        warn_once(("write", str(path.parent)), f"mechsim: model cache {path.parent} is not "
                  f"writable ({exc}); the model is compiled in memory for this run only")
        module = _module(name, source, None)
    attach(module, None if module.__file__ is None else path)
    _loaded[key] = module
    return module, False


def clear_memory_cache() -> None:
    """Forget modules loaded in this process (tests use it to force a disk read)."""
    _loaded.clear()
    _fallback.clear()
    for name in [m for m in sys.modules if m.startswith("mechsim_model_")]:
        del sys.modules[name]
