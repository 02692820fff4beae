"""On-disk cache of generated model modules, keyed by a hash of the model's structure.

The cache directory is `$MECHSIM_CACHE_DIR` if set, else `$XDG_CACHE_HOME/mechsim` or
`~/.cache/mechsim`. Files are written atomically (temporary file, then rename) so parallel
runs of the same scene never read a half-written module. This module must not import sympy.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import sys
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

from .compiled import attach

# Bump when the generated code changes meaning, so stale cache entries are not used.
CODEGEN_VERSION = 7


def cache_dir() -> Path:
    env = os.environ.get("MECHSIM_CACHE_DIR")
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "mechsim"


def structure_key(structure) -> str:
    """A stable hash of a JSON-serialisable structure description."""
    text = json.dumps({"codegen": CODEGEN_VERSION, "structure": structure}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def _import_source(name: str, path: Path | None, source: str | None = None) -> ModuleType:
    if path is not None:
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    else:
        module = ModuleType(name)
        exec(compile(source, f"<mechsim model {name}>", "exec"), module.__dict__)
    return module


_loaded: dict[str, ModuleType] = {}


def load_model(structure, build: Callable[[], str]) -> tuple[ModuleType, bool]:
    """Return (module, from_cache). `build()` produces the module source on a miss."""
    key = structure_key(structure)
    if key in _loaded:
        return _loaded[key], True
    name = f"mechsim_model_{key}"
    path = cache_dir() / f"{name}.py"
    if path.is_file():
        try:
            module = _import_source(name, path)
            if getattr(module, "KEY", None) == key:
                attach(module, path)
                _loaded[key] = module
                return module, True
        except Exception as exc:  # a corrupt entry is rebuilt, not fatal
            warnings.warn(f"mechsim: ignoring unreadable cache entry {path}: {exc}")
    source = build()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=name, suffix=".tmp")
        with os.fdopen(fd, "w") as f:
            f.write(source)
        os.replace(tmp, path)
        module = _import_source(name, path)
        attach(module, path)
    except OSError as exc:
        warnings.warn(f"mechsim: model cache {path.parent} is not writable ({exc}); "
                      "the model is compiled in memory for this run only")
        module = _import_source(name, None, source)
    _loaded[key] = module
    return module, False


def clear_memory_cache() -> None:
    """Forget modules loaded in this process (tests use it to force a disk read)."""
    _loaded.clear()
    for name in [m for m in sys.modules if m.startswith("mechsim_model_")]:
        del sys.modules[name]
