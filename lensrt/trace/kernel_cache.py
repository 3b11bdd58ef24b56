"""Specialised kernel modules loaded from a lensrt-keyed folder, without Warp's code generation.

Warp names a compiled module by a hash of its code. For a module whose ``wp.static`` expressions
depend on unrolled loop variables -- every specialised kernel (:mod:`.specialised`) -- Warp 1.19
can only compute that hash after running its code generator over the whole module, in every new
process, even when the binary is in its kernel cache (about 0.2-0.5 s per module on the host, twice
per report on a GPU). Here such a module is compiled once into a folder of its own, named by a
key that covers everything its code depends on:

- the kernel's own key (precision, lens shape, stream options, tuning) -- the module's contents;
- the source text of every lensrt module (the generators, the shared ``@wp.func`` code, constants);
- Warp's version and the source of its code generator, the Python version, and Warp's resolved
  module options (mode, optimisation level, fast math, ...);

with the compiled files named by Warp itself (CUDA architecture, CPU target) inside it. A later
process finds the binary there and loads it as Warp's ahead-of-time loader does
(``strip_hash=True``: the symbols carry no hash), telling Warp that no static expression is left to
resolve, so its hash is computed without code generation; a missing binary is compiled (code
generation once) and moved into place atomically. A changed source file, Warp or option gives a
new key, so a stale binary is never loaded.

The shortcut touches Warp internals; it runs only on the Warp versions it was written for
(:data:`WARP_VERSIONS`) and when ``LENSRT_KERNEL_CACHE`` is not ``0``. Anything unexpected puts the
module back on Warp's own path (its content hash and cache), which is always correct.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import sys
import tempfile
import threading
from functools import lru_cache
from pathlib import Path
from typing import Any

__all__ = ["WARP_VERSIONS", "enabled", "source_digest", "folder_for", "load_module"]

#: Warp versions whose Module.load / ModuleHasher this shortcut was written and tested against
WARP_VERSIONS = ("1.19.0",)
_LAYOUT = "lensrt-kernel-cache-1"
#: guards _LOCKS
_LOCK = threading.Lock()
#: one lock per (module, device): two different modules load side by side (their native compiles overlap; Warp
#: serialises only its code generation), two threads asking for the same one load it once
_LOCKS: dict[tuple[str, str], threading.Lock] = {}
_DONE: dict[tuple[str, str], str] = {}


def enabled(wp: Any) -> bool:
    """Whether the shortcut applies: a known Warp version and ``LENSRT_KERNEL_CACHE`` not ``0``."""
    if os.environ.get("LENSRT_KERNEL_CACHE", "1").strip() == "0":
        return False
    ctx = getattr(getattr(wp, "_src", None), "context", None)
    return (wp.config.version in WARP_VERSIONS and ctx is not None
            and hasattr(ctx, "_resolve_launch_block_dim") and hasattr(ctx.Module, "_get_compile_output_name"))


@lru_cache(maxsize=1)
def source_digest() -> str:
    """SHA-256 of the source text of every lensrt module and of Warp's code generator (once per process)."""
    h = hashlib.sha256(_LAYOUT.encode())
    h.update(f"python {sys.version_info[0]}.{sys.version_info[1]}".encode())
    pkg = Path(__file__).resolve().parents[1]
    for path in sorted(pkg.rglob("*.py")):
        h.update(str(path.relative_to(pkg)).encode() + b"\0" + path.read_bytes() + b"\0")
    import warp
    h.update(f"warp {warp.config.version}".encode())
    src = Path(warp.__file__).resolve().parent / "_src"
    for name in ("codegen.py", "context.py", "builtins.py", "types.py"):
        p = src / name
        h.update(name.encode() + b"\0" + (p.read_bytes() if p.exists() else b"missing") + b"\0")
    return h.hexdigest()


def folder_for(wp: Any, module: Any, kernel_key: str) -> Path:
    """The folder of ``module``'s binaries: Warp's kernel cache / lensrt_specialised / name_key."""
    options = module.resolve_options(wp.config)
    h = hashlib.sha256(source_digest().encode())
    h.update(kernel_key.encode())
    h.update(repr(sorted((k, repr(v)) for k, v in options.items() if k != "block_dim")).encode())
    return Path(wp.config.kernel_cache_dir) / "lensrt_specialised" / f"{module.name}_{h.hexdigest()[:20]}"


def load_module(module_name: str, kernel_key: str, device: str) -> str:
    """Load specialised module ``module_name`` on ``device`` before its first launch (once per process).

    ``kernel_key`` is the repr of everything the module was generated from. Returns how: ``"cached"``
    (found, no code generation), ``"compiled"`` (built into the folder) or ``"warp"`` (Warp's own path).
    """
    key = (module_name, device)
    done = _DONE.get(key)
    if done is not None:
        return done
    with _LOCK:
        lock = _LOCKS.setdefault(key, threading.Lock())
    with lock:
        done = _DONE.get(key)
        if done is None:
            done = _load(module_name, kernel_key, device)
            _DONE[key] = done
        return done


def _load(module_name: str, kernel_key: str, device: str) -> str:
    from ..device import warp
    wp = warp()
    module = wp.get_module(module_name)
    if not enabled(wp):
        return "warp"
    unresolved = module.has_unresolved_static_expressions
    try:
        wp.set_module_options({"strip_hash": True}, module=module)
        return _load_stripped(wp, module, kernel_key, device)
    except Exception as error:  # Warp's own path: content hash, its cache, always correct
        module.has_unresolved_static_expressions = unresolved
        wp.set_module_options({"strip_hash": False}, module=module)
        if os.environ.get("LENSRT_WARP_VERBOSE", "") != "":
            print(f"lensrt: {module_name} on {device} left to Warp's own cache ({error!r})", file=sys.stderr)
        return "warp"


def _load_stripped(wp: Any, module: Any, kernel_key: str, device: str) -> str:
    """Module.load with a binary path in the keyed folder (compiled into it first when missing)."""
    dev = wp.get_device(device)
    block_dim = wp._src.context._resolve_launch_block_dim(dev, None)
    folder = folder_for(wp, module, kernel_key)
    arch = module._get_compile_arch(dev)
    binary = folder / module._get_compile_output_name(dev, block_dim=block_dim)
    meta = folder / module._get_meta_name(block_dim=block_dim)
    how = "cached"
    if binary.exists() and meta.exists():
        # nothing left for the code generator to resolve before hashing: the binary is named by our key
        module.has_unresolved_static_expressions = False
    else:
        how = "compiled"
        module.get_module_hash(block_dim)  # code generation, as Warp's own load would do
        options = module.resolved_options[block_dim]
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=folder.name + ".", dir=folder.parent))
        try:
            module._compile(dev, str(tmp), binary.name, arch, options=options)
            folder.mkdir(exist_ok=True)
            for f in sorted(tmp.iterdir(), key=lambda p: p == tmp / binary.name):  # the binary last
                os.replace(f, folder / f.name)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    module.load(dev, block_dim=block_dim, binary_path=str(binary), output_arch=arch, meta_path=str(meta))
    return how
