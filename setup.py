"""Packaging glue that pyproject.toml cannot express: the lens library and the scenes live at the
top of the repository (lens_prescriptions/, scenes/) and install inside the package as
lensrt.lens_prescriptions and lensrt.scenes, so a wheel install finds them too."""
from setuptools import find_packages, setup

DATA_PACKAGES = {
    "lensrt.lens_prescriptions": "lens_prescriptions",
    "lensrt.scenes": "scenes",
    "lensrt.scenes.models": "scenes/models",
    "lensrt.scenes.textures": "scenes/textures",
}

setup(
    packages=find_packages(include=["lensrt", "lensrt.*"]) + list(DATA_PACKAGES),
    package_dir=DATA_PACKAGES,
    package_data={name: ["*"] for name in DATA_PACKAGES},
)
