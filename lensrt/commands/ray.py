"""``lensrt ray``: trace one named real ray and print it surface by surface."""
from __future__ import annotations

import argparse
import math

from ._common import add_lens_argument, emit, print_json, lens_config

__all__ = ["register", "ray_report"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("ray", help="trace one real ray (field Hx Hy, pupil Px Py) surface by surface",
                       description="Trace one real ray named by normalised field (Hx, Hy) and pupil (Px, Py) "
                                   "coordinates and print, per surface, the intersection (x, y, z = sag), "
                                   "direction cosines after refraction and the angles of incidence and "
                                   "refraction.")
    add_lens_argument(p)
    p.add_argument("--hx", type=float, default=0.0, help="normalised field x (default 0)")
    p.add_argument("--hy", type=float, default=0.0, help="normalised field y (default 0)")
    p.add_argument("--px", type=float, default=0.0, help="normalised pupil x (default 0)")
    p.add_argument("--py", type=float, default=0.0, help="normalised pupil y (default 0)")
    p.add_argument("--wavelength-nm", type=float, default=None, help="wavelength (default: the lens's primary)")
    p.add_argument("--aim", choices=["paraxial", "chief", "real"], default="paraxial",
                   help="ray aiming: paraxial entrance pupil (default), chief ray at the real stop centre "
                        "with paraxial pupil offsets (CODE V), or iterated to the real stop")
    p.add_argument("--precision", choices=["float64", "float32"], default="float64")
    p.add_argument("--device", default=None, help="cpu, cuda or cuda:N (default: cuda if present, else cpu)")
    p.add_argument("--no-clip", action="store_true", help="ignore clear apertures and the iris")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_ray)


def ray_report(lens, hx: float, hy: float, px: float, py: float, wavelength_nm: float | None = None,
               aim: str = "paraxial", precision: str = "float64", device: str | None = None,
               clip: bool = True) -> dict:
    """Trace one named ray; the JSON object ``lensrt ray --json`` prints."""
    from ..errors import LensrtError
    from ..trace import make_rays, trace
    from ..trace.status import OK, STATUS_NAMES
    for name, v in (("hx", hx), ("hy", hy), ("px", px), ("py", py)):
        if not math.isfinite(v):
            raise LensrtError(f"--{name} {v!r} is not a finite number")
    wl = lens.wavelengths.primary_nm if wavelength_nm is None else float(wavelength_nm)
    if wavelength_nm is not None:
        lens.check_wavelengths(wl)  # an ExtrapolationWarning where a glass's formula is extrapolated
    rays = make_rays(lens, hx, hy, px, py, wl, aim, device)
    res = trace(lens, rays, precision, device, clip=clip, record=True)
    st, where = int(res.status[0]), int(res.surface[0])
    n = lens.n_surfaces
    if st == OK:
        rows = n + 1
    elif STATUS_NAMES[st] in ("VIGNETTED", "TIR"):
        rows = where + 1
    else:
        rows = max(where, 0)
    surfaces = []
    for i in range(rows):
        r = res.records[0, i]
        surfaces.append({"surface": "IMG" if i == n else i + 1, "x_mm": r[0], "y_mm": r[1], "z_mm": r[2],
                         "L": r[3], "M": r[4], "N": r[5], "incidence_deg": math.degrees(r[6]),
                         "refraction_deg": math.degrees(r[7]), "length_mm": r[8]})
    return {
        "lens": lens.name, "hx": hx, "hy": hy, "px": px, "py": py, "wavelength_nm": wl, "aim": aim,
        "aim_converged": bool(res.aimed[0]), "precision": precision, "device": res.device,
        "status": STATUS_NAMES[st], "failed_surface": None if st == OK else (
            "IMG" if where >= n else where + 1),
        "image_x_mm": float(res.position_mm[0, 0]) if st == OK else None,
        "image_y_mm": float(res.position_mm[0, 1]) if st == OK else None,
        "image_z_mm": float(res.position_mm[0, 2]) if st == OK else None,
        "direction": [float(v) for v in res.direction[0]],
        "opl_mm": float(res.opl_mm[0]) if st == OK else None,
        "surfaces": surfaces,
    }


def cmd_ray(args: argparse.Namespace) -> int:
    from ..io.table import format_table
    from ..loading import load_lens
    lens = load_lens(args.file, config=lens_config(args))
    rep = ray_report(lens, args.hx, args.hy, args.px, args.py, args.wavelength_nm, args.aim, args.precision,
                     args.device, not args.no_clip)
    if args.json:
        print_json(rep)
        return 0
    emit(f"{lens.name or lens.path}: ray Hx={args.hx:g} Hy={args.hy:g} Px={args.px:g} Py={args.py:g} at "
         f"{rep['wavelength_nm']:g} nm, aim {args.aim}, {args.precision} on {rep['device']}")
    if not rep["aim_converged"]:
        emit("warning: ray aiming did not converge; the ray is aimed at the paraxial entrance pupil")
    rows = [[s["surface"], s["x_mm"], s["y_mm"], s["z_mm"], s["L"], s["M"], s["N"], s["incidence_deg"],
             s["refraction_deg"]] for s in rep["surfaces"]]
    emit(format_table(rows, ["surf", "x_mm", "y_mm", "z_mm", "L", "M", "N", "AOI_deg", "AOR_deg"], digits=6))
    if rep["status"] == "OK":
        L, M, N = rep["direction"]
        emit(f"status OK: image x = {rep['image_x_mm']:.6f} mm, y = {rep['image_y_mm']:.6f} mm at "
             f"z = {rep['image_z_mm']:.6f} mm; direction ({L:.6f}, {M:.6f}, {N:.6f}); "
             f"OPL {rep['opl_mm']:.6f} mm")
    else:
        emit(f"status {rep['status']} at surface {rep['failed_surface']}")
    emit("(z_mm is the sag at the intersection, measured from each surface's vertex)")
    return 0
