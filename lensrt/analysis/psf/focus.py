"""Where the PSF is observed: the lens file's image surface, the paraxial image plane, best focus, or a shift.

A focus is written ``BASE[+-SHIFT]`` or ``SHIFT`` (mm along +z):

``image``
    the lens file's image surface (the sensor where the file puts it); a bare
    number is a shift from it, e.g. ``0.05``;
``paraxial``
    the paraxial image of the object plane at the primary wavelength
    (:func:`lensrt.paraxial.first_order`);
``best``
    best focus, defined here as the plane z that minimises the RMS spot
    radius (about its centroid) of the **axial** point at the **primary**
    wavelength, over all rays through the real pupil weighted as the stream
    kernel weights them: :mod:`lensrt.trace.focus`, the one best-focus routine of every table, of
    ``--focus best`` and of the render (closed form in z; the pupil's edge resolved by sub-sampling).

``best+0.01`` is 10 um behind best focus.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass


from ...errors import LensrtError
from ...prescription.frames import travel_signs
from ...prescription.model import Lens

__all__ = ["FOCUS_BASES", "FocusSpec", "parse_focus", "best_focus_z_mm", "focus_plane"]

FOCUS_BASES = ("image", "paraxial", "best")


@dataclass(frozen=True)
class FocusSpec:
    """A focus: ``base`` in :data:`FOCUS_BASES` and a shift ``offset_mm`` along +z."""

    base: str = "image"
    offset_mm: float = 0.0

    def __str__(self) -> str:
        if self.offset_mm == 0.0:
            return self.base
        return f"{self.base}{self.offset_mm:+g}"


def parse_focus(text: str | float | None) -> FocusSpec:
    """``"best"``, ``"paraxial-0.02"``, ``"0.05"`` (from the image surface) -> :class:`FocusSpec`."""
    if text is None:
        return FocusSpec()
    if isinstance(text, (int, float)):
        return FocusSpec("image", float(text))
    s = str(text).strip().lower()
    m = re.fullmatch(r"(image|paraxial|best)?\s*([+-]\s*[0-9.eE+-]+|[0-9.eE+-]+)?", s)
    if not s or m is None or (m.group(1) is None and m.group(2) is None):
        raise LensrtError(f"bad focus {text!r}",
                          hint="use image, paraxial, best, a shift in mm (0.05), or e.g. best+0.01")
    base = m.group(1) or "image"
    off = 0.0
    if m.group(2):
        try:
            off = float(m.group(2).replace(" ", ""))
        except ValueError:
            raise LensrtError(f"bad focus shift in {text!r}", hint="e.g. best+0.01 (mm)") from None
    if not math.isfinite(off):
        raise LensrtError(f"focus shift {off!r} mm is not finite")
    return FocusSpec(base, off)


def best_focus_z_mm(lens: Lens, wavelength_nm: float | None = None, z0_mm: float | None = None,
                    device: str | None = None) -> tuple[float, float]:
    """Best focus of the axial point at one wavelength (:mod:`lensrt.trace.focus`, the one routine every
    table uses): (z of the plane (mm), RMS spot radius there (mm))."""
    from ...trace.focus import best_focus_plane, focus_moments
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    if z0_mm is None:
        from ...paraxial import first_order
        z0_mm = first_order(lens, wl).image_z_mm
        if not math.isfinite(z0_mm):
            z0_mm = lens.image_z_mm
    plane = best_focus_plane([focus_moments(lens, wl, z0_mm=z0_mm, device=device)])
    return plane.z_mm, plane.rms_radius_mm


def _refuse_virtual_image(lens: Lens, spec: FocusSpec, z_mm: float) -> None:
    """One clear error when the observation plane lies in front of the last surface because the image is virtual."""
    from ...paraxial import first_order
    try:
        fo = first_order(lens)
    except LensrtError:
        return
    if fo.image_virtual:
        raise LensrtError(
            f"focus {spec}: the lens forms a virtual image (z = {fo.image_z_mm:.6g} mm, {abs(fo.image_distance_mm):.4g} "
            f"mm in front of the last vertex): no light reaches a plane there, so PSFs, MTFs and wavefronts "
            f"(observed on a plane behind the last surface) are not defined",
            hint="lensrt compare gives spots on the virtual image plane (rays extended backwards); to image it, "
                 "add a lens behind it (e.g. an ideal paraxial surface)")


def focus_plane(lens: Lens, spec: FocusSpec | str | None = None, device: str | None = None) -> dict:
    """The observation plane of a focus: ``{"z_mm", "base", "base_z_mm", "offset_mm", ...}``.

    ``z_mm`` is in the lens frame (z from the first vertex); ``shift_from_image_mm``
    is from the lens file's image surface.
    """
    spec = parse_focus(spec) if not isinstance(spec, FocusSpec) else spec
    from ...paraxial.first_order import refuse_afocal
    refuse_afocal(lens, "a PSF, MTF or wavefront (observed on an image plane)")
    info: dict = {"focus": str(spec), "base": spec.base, "offset_mm": spec.offset_mm}
    if spec.base == "image":
        base = lens.image_z_mm
    elif spec.base == "paraxial":
        from ...paraxial import first_order
        base = first_order(lens).image_z_mm
        if not math.isfinite(base):
            raise LensrtError("the paraxial image is at infinity (afocal)", hint="use --focus image or best")
        info["definition"] = "paraxial image of the object plane, primary wavelength"
    elif spec.base == "best":
        base, rms = best_focus_z_mm(lens, device=device)
        info["definition"] = ("minimum RMS spot radius of the axial point at the primary wavelength "
                              "(closed-form parabola over a 128 x 128 real-pupil ray grid)")
        info["axial_rms_radius_mm"] = rms
    else:  # pragma: no cover - parse_focus allows only the bases above
        raise LensrtError(f"unknown focus base {spec.base!r}")
    z = float(base + spec.offset_mm)
    last_z = float(lens.vertex_z_mm()[lens.n_surfaces - 1])
    travel = travel_signs(lens)[-1]  # -1 after an odd number of mirrors: the image lies toward -z
    if not (z - last_z) * travel > 0.0:  # rays would be extended backwards through the lens to a plane in front
        _refuse_virtual_image(lens, spec, z)
        raise LensrtError(f"focus {spec}: the observation plane z = {z:.6g} mm is not behind the last surface "
                          f"(z = {last_z:.6g} mm)", hint="give a smaller shift")
    info["base_z_mm"] = float(base)
    info["z_mm"] = z
    info["shift_from_image_mm"] = float(base + spec.offset_mm - lens.image_z_mm)
    return info
