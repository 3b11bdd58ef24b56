"""Raw frames as DNG through pidng (optional: ``pip install 'lensrt[dng]'``).

pidng (the one pip-installable DNG writer; last release 4.0.9, May 2022, built from source)
writes an uncompressed 16-bit CFA DNG. lensrt adds the CFA pattern (Bayer or any repeating
pattern, X-Trans included), black and white levels, ColorMatrix1 (XYZ -> camera native,
from the fitted characterisation matrix and white balance, illuminant D65) and AsShotNeutral.
Verified here by a round trip through rawpy (LibRaw): the mosaic, pattern and levels read back
exactly for Bayer frames. Averaged / float frames are rounded to uint16.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import LensrtError
from ..sensor.detector import RawFrame
from .paths import output_file

__all__ = ["write_dng"]


def _rationals(values, den: int = 10000) -> list[list[int]]:
    return [[int(round(float(v) * den)), den] for v in np.ravel(values)]


def write_dng(path: str | Path, raw: RawFrame, xyz_to_camera: np.ndarray | None = None,
              as_shot_neutral: np.ndarray | None = None) -> Path:
    """Write ``raw`` as a DNG file.

    Parameters
    ----------
    xyz_to_camera : 3x3, optional
        DNG ColorMatrix1 (XYZ under D65 -> camera native RGB); identity if not given.
    as_shot_neutral : (3,), optional
        Camera-native response of the adopted white (1 / white-balance multipliers).
    """
    try:
        from pidng.core import RAW2DNG, DNGTags, Tag
        from pidng.defs import CalibrationIlluminant, DNGVersion, Orientation, PhotometricInterpretation
    except ImportError:
        raise LensrtError("DNG output needs the optional pidng package", hint="pip install 'lensrt[dng]' (or use .exr)") from None
    path = Path(path)
    if path.suffix.lower() != ".dng":
        raise LensrtError(f"DNG file name {path} must end in .dng")
    dn = np.clip(np.round(raw.dn), 0, 65535).astype(np.uint16)
    h, w = dn.shape
    pr, pc = raw.cfa.shape
    t = DNGTags()
    t.set(Tag.ImageWidth, w)
    t.set(Tag.ImageLength, h)
    t.set(Tag.TileWidth, w)
    t.set(Tag.TileLength, h)
    t.set(Tag.Orientation, Orientation.Horizontal)
    t.set(Tag.PhotometricInterpretation, PhotometricInterpretation.Color_Filter_Array)
    t.set(Tag.SamplesPerPixel, 1)
    t.set(Tag.BitsPerSample, 16)
    t.set(Tag.CFARepeatPatternDim, [pr, pc])
    t.set(Tag.CFAPattern, [int(c) for row in raw.cfa.tile for c in row])
    t.set(Tag.BlackLevel, int(round(raw.black_level_dn)))
    t.set(Tag.WhiteLevel, int(raw.white_level_dn))
    m = np.eye(3) if xyz_to_camera is None else np.asarray(xyz_to_camera, float)
    t.set(Tag.ColorMatrix1, _rationals(m))
    t.set(Tag.CalibrationIlluminant1, CalibrationIlluminant.D65)
    t.set(Tag.AsShotNeutral, _rationals(np.ones(3) if as_shot_neutral is None else as_shot_neutral))
    t.set(Tag.BaselineExposure, [[0, 100]])
    t.set(Tag.Make, "lensrt")
    t.set(Tag.Model, str(raw.meta.get("sensor", "simulated")))
    t.set(Tag.DNGVersion, DNGVersion.V1_4)
    t.set(Tag.DNGBackwardVersion, DNGVersion.V1_2)
    output_file(path)
    writer = RAW2DNG()
    writer.options(t, path=str(path.parent), compress=False)
    try:
        writer.convert(dn, filename=path.stem)
    except Exception as err:  # noqa: BLE001 - pidng raises plain exceptions
        raise LensrtError(f"pidng could not write the DNG: {err}", path=path) from None
    return path
