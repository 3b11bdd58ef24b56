"""Stage 5: scenes through the lens -- scene files, spectra, scene-side kernels, the render plan."""
