"""Regenerate the image textures used by the built-in scenes (numpy + PIL, no downloaded assets).

* ``hue_wheel.png`` (256 x 256, 8-bit sRGB): a hue/saturation wheel (hue by angle, saturation
  by radius, full value) on a background of eight neutral grey steps (sRGB 0.1 ... 0.9); a colour
  target for image textures, which lensrt turns into reflectance by the Mallett-Yuksel 2019 basis.
"""
from __future__ import annotations

import colorsys
from pathlib import Path

import numpy as np
from PIL import Image

HERE = Path(__file__).resolve().parent


def hue_wheel(n: int = 256) -> np.ndarray:
    y, x = (np.mgrid[0:n, 0:n] + 0.5) / n * 2.0 - 1.0
    r = np.hypot(x, y)
    hue = (np.arctan2(-y, x) / (2 * np.pi)) % 1.0
    img = np.empty((n, n, 3))
    steps = np.floor((x + 1.0) / 2.0 * 8).clip(0, 7)
    grey = 0.1 + 0.8 * steps / 7.0
    for i in range(n):
        for j in range(n):
            if r[i, j] <= 0.8:
                img[i, j] = colorsys.hsv_to_rgb(hue[i, j], min(r[i, j] / 0.8, 1.0), 1.0)
            else:
                img[i, j] = grey[i, j]
    return (img * 255 + 0.5).astype(np.uint8)


def main() -> None:
    Image.fromarray(hue_wheel()).save(HERE / "hue_wheel.png", optimize=True)


if __name__ == "__main__":
    main()
