"""Scenes: TOML scene files, their immutable model, and the packed Warp data the render kernels read.

Files:

- ``load``       load_scene: a scene file, every key checked, into a Scene
- ``parse``      the scene file's tables and values
- ``model``      Scene and its records (planes, meshes, lights, camera, render settings)
- ``textures``   procedural and image textures
- ``pack``       Scene -> SceneData (Warp arrays)
- ``kernels``    @wp.struct SceneData and the scene queries of the render kernels
- ``reference``  a float64 NumPy reference of the scene queries (the tests' oracle)
"""
from __future__ import annotations

from ...core.lazy import lazy_face

#: public name -> the module of this package that defines it (imported on first use)
__getattr__, __all__ = lazy_face(__name__, {
    "load_scene": "load",
    "Scene": "model",
    "pack_scene": "pack",
})
