"""Regenerate the still-life models used by ``scenes/still_life_mesh.toml`` (run from anywhere).

Every model is made with ``trimesh.creation`` (no downloaded assets), in metres,
standing on its base at y = 0, and written in a different format so that each
reader of the scene loader is exercised:

* ``torus.ply``     upright torus (ring in the x-y plane, facing the camera), major radius 0.08 m, tube radius 0.03 m (64 x 32 segments, 4096 triangles), binary PLY
* ``icosphere.obj`` icosphere of radius 0.06 m, 3 subdivisions (1280 triangles), Wavefront OBJ
* ``cone.stl``      cone of radius 0.05 m, height 0.15 m (64 sections), binary STL
* ``vase.glb``      a lathe-turned vase profile revolved with ``trimesh.creation.revolve``
                    (96 sections), glTF binary
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent


def main() -> None:
    torus = trimesh.creation.torus(major_radius=0.08, minor_radius=0.03, major_sections=64, minor_sections=32)
    torus.apply_translation([0, 0.11, 0])
    torus.export(HERE / "torus.ply")

    ico = trimesh.creation.icosphere(subdivisions=3, radius=0.06)
    ico.apply_translation([0, 0.06, 0])
    ico.export(HERE / "icosphere.obj")

    cone = trimesh.creation.cone(radius=0.05, height=0.15, sections=64)
    cone.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))  # apex up (+y)
    cone.export(HERE / "cone.stl")

    # vase: profile (radius, height) revolved about the z axis, then stood up on y
    h = np.linspace(0.0, 0.22, 23)
    r = 0.035 + 0.03 * np.sin(np.pi * h / 0.22 * 1.2) ** 2
    profile = np.column_stack([np.concatenate([[0.0], r, [0.0]]), np.concatenate([[0.0], h, [0.22]])])
    vase = trimesh.creation.revolve(profile, sections=96)
    vase.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    vase.export(HERE / "vase.glb")


if __name__ == "__main__":
    main()
