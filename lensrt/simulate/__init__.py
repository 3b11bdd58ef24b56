"""Image simulation: a photograph (and its depth map) through a real lens onto the sensor.

Stage: beside :mod:`lensrt.pipeline` and :mod:`lensrt.studies`, above :mod:`lensrt.analysis`; it uses
the analysis stage's real-ray tools (chief-ray placement, pupil boxes, the stream kernel), the sensor
and ISP stages and :mod:`lensrt.io`; only the CLI imports it. See docs/guide/simulate.md.

Files: ``inputs.py`` (image and depth readers), ``spectral.py`` (RGB -> bands), ``optics.py`` (camera,
real mapping, relative illumination), ``psf_grid.py`` (PSF nodes, cached), ``convolve.py`` (FFTs cell by
cell on the host), ``compose.py`` (layers, fill, warp, compositing), ``banding.py`` (the host blur in bands
of rows within a memory budget), ``device.py`` (the same blur with Warp kernels and tile FFTs on a device),
``pipeline.py`` (``simulate``), ``outputs.py`` (files, sensor and ISP). In
Python::

    from lensrt import load_lens
    from lensrt.simulate import SimulateOptions, read_image_linear, simulate, write_outputs
    sim = simulate(read_image_linear("photo.png"), load_lens("dgauss_50mm_f2"), None,
                   SimulateOptions(sensor="full-frame", focus_m=3.0, f_number=2.8))
    write_outputs(sim, "out/photo")          # out/photo.exr, .png, .json
"""
from __future__ import annotations

from .inputs import read_depth_m, read_image_linear
from .outputs import write_outputs
from .pipeline import SimulateOptions, Simulation, simulate

__all__ = ["simulate", "SimulateOptions", "Simulation", "read_image_linear", "read_depth_m", "write_outputs"]
