"""Specialised kernel modules from lensrt's keyed folder (lensrt.trace.kernel_cache): a fresh process loads a
compiled module without Warp's code generation and traces the same bits as Warp's own path; the folder's key
changes with everything the code depends on."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from lensrt.device import warp
from lensrt.trace import kernel_cache

ROOT = Path(__file__).resolve().parents[2]

# one specialised float32 store trace of the double Gauss in a fresh process: how the module was loaded, how
# many times Warp's code generator ran over a specialised module, and the traced rays
SCRIPT = r"""
import json, sys
import numpy as np
import warp
if sys.argv[1]:
    warp.config.kernel_cache_dir = sys.argv[1]
from warp._src import context
built = []
init = context.ModuleBuilder.__init__
def spy(self, module, *a, **k):
    if module.name.startswith("lensrt_fast"):
        built.append(module.name)
    return init(self, module, *a, **k)
context.ModuleBuilder.__init__ = spy
from lensrt.loading import load_lens
from lensrt.trace import api, kernel_cache
hows = []
load = kernel_cache.load_module
kernel_cache.load_module = lambda *a: hows.append(load(*a)) or hows[-1]
lens = load_lens(None)
rays = api.make_rays(lens, 0.0, np.linspace(-1, 1, 9), np.linspace(-1, 1, 41)[:, None], 0.25,
                     wavelength_nm=np.linspace(440.0, 660.0, 41)[:, None])
r = api.trace(lens, rays, "float32", "cpu", kernel="specialised")
bits = np.concatenate([r.position_mm.ravel(), r.direction.ravel(), r.opl_mm, r.status.astype(float)])
print(json.dumps({"how": hows, "built": built, "kernel": r.kernel, "bits": bits.tobytes().hex()}))
"""


def _run(cache_dir: str, enabled: bool) -> dict:
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)  # keep where warp is
    env = dict(os.environ, PYTHONPATH=path, LENSRT_KERNEL_CACHE="1" if enabled else "0")
    out = subprocess.run([sys.executable, "-c", SCRIPT, cache_dir], env=env, capture_output=True, text=True,
                         check=True, timeout=600)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_a_fresh_process_loads_the_compiled_module_without_code_generation_and_traces_the_same_bits(tmp_path):
    if not kernel_cache.enabled(warp()):
        pytest.skip(f"Warp {warp().config.version} is not one the shortcut was written for")
    # Warp's own path (content hash, code generation in every process): the reference bits
    ref = _run(str(tmp_path / "warp"), enabled=False)
    assert ref["how"] == ["warp"] and ref["kernel"] == "specialised" and ref["built"]
    # first use: compiled into the keyed folder (code generation once)
    first = _run(str(tmp_path / "lensrt"), enabled=True)
    assert first["how"] == ["compiled"] and first["built"]
    folders = list((tmp_path / "lensrt").glob("*/lensrt_specialised/*"))  # Warp adds its version to the path
    assert len(folders) == 1 and any(f.suffix == ".o" for f in folders[0].iterdir())
    # a new process: found, loaded without running the code generator, same rays bit for bit
    again = _run(str(tmp_path / "lensrt"), enabled=True)
    assert again["how"] == ["cached"] and again["built"] == []
    assert first["bits"] == ref["bits"] and again["bits"] == ref["bits"]


def _fake_module(options: dict) -> SimpleNamespace:
    return SimpleNamespace(name="lensrt_fast_store_float32_0123456789ab", resolve_options=lambda config: dict(options))


def test_the_folder_key_covers_the_kernel_key_the_options_and_the_sources(monkeypatch):
    wp = warp()
    base = {"mode": "release", "fast_math": False, "block_dim": 256}
    a = kernel_cache.folder_for(wp, _fake_module(base), "('store', 'float32', shape A)")
    assert a.parent.name == "lensrt_specialised" and a.name.startswith("lensrt_fast_store_float32_0123456789ab_")
    assert a == kernel_cache.folder_for(wp, _fake_module(base), "('store', 'float32', shape A)")
    assert a != kernel_cache.folder_for(wp, _fake_module(base), "('store', 'float32', shape B)")
    assert a != kernel_cache.folder_for(wp, _fake_module(base | {"fast_math": True}), "('store', 'float32', shape A)")
    assert a != kernel_cache.folder_for(wp, _fake_module(base | {"mode": "debug"}), "('store', 'float32', shape A)")
    # the launch's block size is Warp's own file name's business, not the folder's
    assert a == kernel_cache.folder_for(wp, _fake_module(base | {"block_dim": 1}), "('store', 'float32', shape A)")
    monkeypatch.setattr(kernel_cache, "source_digest", lambda: "another source tree")
    assert a != kernel_cache.folder_for(wp, _fake_module(base), "('store', 'float32', shape A)")


def test_the_source_digest_reads_every_lensrt_module(tmp_path, monkeypatch):
    kernel_cache.source_digest.cache_clear()
    try:
        d = kernel_cache.source_digest()
        assert len(d) == 64 and d == kernel_cache.source_digest()
        # a changed kernel source (here: the shared surface code) gives another digest
        surfaces = ROOT / "lensrt" / "trace" / "kernels" / "surfaces.py"
        real = Path.read_bytes

        def edited(self):
            data = real(self)
            return data + b"\n# edited\n" if self.resolve() == surfaces.resolve() else data
        monkeypatch.setattr(Path, "read_bytes", edited)
        kernel_cache.source_digest.cache_clear()
        assert kernel_cache.source_digest() != d
    finally:
        monkeypatch.undo()
        kernel_cache.source_digest.cache_clear()


def test_switched_off_by_the_environment(monkeypatch):
    monkeypatch.setenv("LENSRT_KERNEL_CACHE", "0")
    assert not kernel_cache.enabled(warp())
