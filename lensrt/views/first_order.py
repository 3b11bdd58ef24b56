"""The Gaussian picture of a lens as a person or a program reads it: ``lensrt info``'s data, and its
first-order and Seidel tables (shared by ``lensrt info`` and the report)."""
from __future__ import annotations

import math
from typing import Any

__all__ = ["info_data", "first_order_rows", "format_value", "seidel_rows", "virtual_image_line", "afocal_line",
           "parabasal_data", "parabasal_rows"]

#: the first-order method of a centred lens (and of one whose unfolded axis the real rays confirm)
YNU_METHOD = "paraxial ynu"


def info_data(lens, wavelength_nm: float | None = None, object_distance_mm: float | None = None,
              sensor: str | None = None, coc_mm: float | None = None) -> dict[str, Any]:
    """Everything ``lensrt info --json`` prints, as a dict (infinities as ``inf``)."""
    from ..errors import LensrtError
    from ..paraxial import first_order, seidel_sums
    from ..paraxial import photographic as ph

    if wavelength_nm is not None and not (math.isfinite(wavelength_nm) and 200.0 <= wavelength_nm <= 20000.0):
        raise LensrtError(f"--wavelength-nm {wavelength_nm:g} is outside 200..20000 nm",
                          hint="wavelengths are in nanometres, e.g. 587.56")
    if object_distance_mm is not None and (math.isnan(object_distance_mm) or object_distance_mm <= 0):
        raise LensrtError(f"--object-distance-mm {object_distance_mm:g} must be positive",
                          hint="give the distance from the object to the first vertex in mm, or inf")
    if wavelength_nm is not None:
        lens.check_wavelengths(wavelength_nm)  # an ExtrapolationWarning where a glass's formula is extrapolated
    fo = first_order(lens, wavelength_nm, object_distance_mm)
    if fo.afocal:  # a telescope or a plate: pupils and angular magnification, no focal data or Seidel sums
        if sensor is not None:
            raise LensrtError("the lens is afocal: it forms no image on a sensor", hint="leave out --sensor")
        return {"lens": lens.name, "path": lens.path, **fo.to_dict(),
                "first_order_method": YNU_METHOD + (" (unfolded axis)" if fo.unfolded_axis else ""),
                "field_image_heights_mm": list(fo.field_image_heights_mm), "seidel": None,
                "warnings": [w.to_dict() for w in lens.warnings]}
    sums = seidel_sums(lens, fo.wavelength_nm, object_distance_mm)
    data: dict[str, Any] = {"lens": lens.name, "path": lens.path}
    data.update(fo.to_dict())
    data.update(parabasal_data(lens, fo, object_distance_mm))
    # every approximation the reader made (glass substitutions, model glasses, ignored keywords, defaults)
    data["warnings"] = [w.to_dict() for w in lens.warnings]
    data["field_image_heights_mm"] = list(fo.field_image_heights_mm)
    data["seidel"] = sums.to_dict()
    data["third_order_transverse"] = {(f"{k}_per_mm" if k == "PTZ" else f"{k}_mm"): v
                                      for k, v in sums.transverse_totals().items()}
    if sensor is None:
        if coc_mm is not None:
            raise LensrtError("--coc-mm needs --sensor", hint="add --sensor full-frame (or another format)")
        return data
    fmt = ph.sensor_format(sensor)
    c = fmt.coc_mm if coc_mm is None else float(coc_mm)
    if not (math.isfinite(c) and c > 0):
        raise LensrtError(f"--coc-mm {c:g} must be a positive diameter in mm")
    f, N, s_ep = fo.front_focal_length_mm, fo.f_number, fo.entrance_pupil_distance_mm
    b = fo.bellows_factor
    afov = {k: math.degrees(ph.afov_rad(d, fo.efl_mm, b)) for k, d in
            (("horizontal", fmt.width_mm), ("vertical", fmt.height_mm), ("diagonal", fmt.diagonal_mm))}
    focus_u = math.inf if fo.object_distance_mm is None else fo.object_distance_mm + fo.entrance_pupil_z_mm
    dof = ph.depth_of_field_mm(focus_u, f, N, c, s_ep)
    z_ep = fo.entrance_pupil_z_mm
    data["sensor"] = {
        "name": fmt.name, "width_mm": fmt.width_mm, "height_mm": fmt.height_mm, "diagonal_mm": fmt.diagonal_mm,
        "coc_mm": c, "crop_factor": fmt.crop_factor,
        "equivalent_focal_length_mm": float(ph.equivalent_focal_length_mm(fo.efl_mm, fmt.crop_factor)),
        "bellows_factor": b, "afov_deg": afov,
        "image_half_diagonal_mm": 0.5 * fmt.diagonal_mm,
        "depth_of_field": {
            "focus_distance_from_entrance_pupil_mm": focus_u,
            "near_from_entrance_pupil_mm": dof.near_mm, "far_from_entrance_pupil_mm": dof.far_mm,
            "near_z_mm": z_ep - dof.near_mm, "far_z_mm": z_ep - dof.far_mm, "total_mm": dof.total_mm,
            "hyperfocal_from_entrance_pupil_mm": dof.hyperfocal_mm, "hyperfocal_z_mm": z_ep - dof.hyperfocal_mm,
        },
    }
    return data


def virtual_image_line(d: dict[str, Any]) -> str:
    """One sentence on a virtual image (``d`` from :func:`info_data` with ``image_virtual``): where it lies and why.

    Three cases: a diverging lens (EFL < 0), an object inside the front focal point of a converging lens
    (a magnifier), or a converging beam that crosses before the last surface (the image surface of such a
    file sits where the diverging rays meet when extended backwards).
    """
    where = (f"virtual image: the rays leave the last surface diverging; extended backwards they meet "
             f"{abs(d['image_distance_mm']):.4g} mm in front of the last vertex (z = {d['image_z_mm']:.4g} mm)")
    if d["efl_mm"] < 0.0:
        why = f"a diverging lens, EFL {d['efl_mm']:.4g} mm"
    elif d["object_distance_mm"] is not None and d["magnification"] > 0.0:
        why = f"the object is inside the front focal point, z = {d['front_focal_z_mm']:.4g} mm"
    else:
        why = "the beam comes to a focus before the last surface"
    upright = "" if d["object_distance_mm"] is None else f", m = {d['magnification']:+.4g}"
    return f"{where} ({why}{upright})"


def afocal_line(d: dict[str, Any]) -> str:
    """One sentence for an afocal lens (``d`` from :func:`info_data` with ``afocal``)."""
    return (f"afocal: angular magnification {d['angular_magnification']:.6g}; entrance pupil z = "
            f"{d['entrance_pupil_z_mm']:.6g} mm, diameter {d['entrance_pupil_diameter_mm']:.6g} mm; exit pupil "
            f"z = {format_value(d['exit_pupil_z_mm'], '.6g')} mm, diameter {d['exit_pupil_diameter_mm']:.6g} mm "
            f"(pupil magnification {d['pupil_magnification']:.6g}); no focal points or f-number"
            + ("; an object at infinity has its image at infinity" if d["object_distance_mm"] is None else
               f"; the object's image lies at z = {d['image_z_mm']:.6g} mm"
               f"{' (virtual)' if d['image_virtual'] else ''}, magnification {d['magnification']:.6g}"))


def format_value(v: Any, spec: str = ".4f") -> str:
    if v is None:
        return "inf"
    if isinstance(v, float) and math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return format(v, spec)


def parabasal_data(lens, fo, object_distance_mm: float | None = None) -> dict[str, Any]:
    """``first_order_method`` and, for a lens with tilts or decenters, ``parabasal``: first-order data from
    real rays about the central field's chief ray (:mod:`lensrt.analysis.parabasal`).

    The method is ``"real-ray parabasal about chief ray"`` when those data differ from the y-nu trace of the
    unfolded axis (a genuinely decentred or tilted system: more than 1e-6 relative in the EFL of either
    section, or for a finite object in its magnification); a lens whose unfolded axis they confirm (flat fold
    mirrors, tilted and decentred as they may be; a lens shifted as a whole) keeps ``"paraxial ynu"``. Back
    focal distances are not compared: they run from the chief ray's hit on the last surface, which a
    decentred fold mirror moves along the beam. ``parabasal_error`` says why the real rays could not give them.
    """
    from ..analysis.parabasal import FIRST_ORDER_METHOD, parabasal_first_order
    from ..errors import LensrtError
    if not fo.unfolded_axis:
        return {"first_order_method": YNU_METHOD}
    try:
        p = parabasal_first_order(lens, fo.wavelength_nm, object_distance_mm)
    except LensrtError as exc:
        return {"first_order_method": YNU_METHOD + " (unfolded axis)", "parabasal": None,
                "parabasal_error": str(exc)}
    pairs = [(p.efl_y_mm, fo.efl_mm), (p.efl_x_mm, fo.efl_mm)]
    if fo.object_distance_mm is not None:
        pairs += [(p.magnification_y, fo.magnification), (p.magnification_x, fo.magnification)]
    agree = all(abs(a - b) <= 1e-6 * max(abs(b), 1e-9) for a, b in pairs)
    return {"first_order_method": YNU_METHOD + " (unfolded axis)" if agree else FIRST_ORDER_METHOD,
            "parabasal": p.to_dict()}


def parabasal_rows(d: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(quantity, value, unit) rows of the parabasal data in :func:`info_data`'s dict ([] if it has none)."""
    p = d.get("parabasal")
    if not p:
        return []
    pair = lambda a, b, spec=".4f": f"{format_value(p[a], spec)} / {format_value(p[b], spec)}"  # noqa: E731
    rows = [("EFL y-z / x-z section", pair("efl_y_mm", "efl_x_mm"), "mm")]
    if d["object_distance_mm"] is None:
        rows += [("back focal distance y-z / x-z (along the chief ray)", pair("bfl_y_mm", "bfl_x_mm"), "mm"),
                 ("f-number y-z / x-z", pair("f_number_y", "f_number_x"), "")]
    else:
        rows += [("magnification y-z / x-z", pair("magnification_y", "magnification_x", ".6f"), ""),
                 ("image distance y-z / x-z (along the chief ray)", pair("image_distance_y_mm", "image_distance_x_mm"),
                  "mm")]
    rows += [("entrance / exit pupil distance (along the chief ray)",
              pair("entrance_pupil_distance_mm", "exit_pupil_distance_mm"), "mm"),
             ("entrance / exit pupil diameter", pair("entrance_pupil_diameter_mm", "exit_pupil_diameter_mm"), "mm"),
             ("pupil magnification", format_value(p["pupil_magnification"]), ""),
             ("x-y coupling of the parabasal matrix", format_value(p["coupling"], ".3g"), "")]
    return [("first-order method", d["first_order_method"], "")] + [(f"{a} [parabasal]", b, c) for a, b, c in rows]


def first_order_rows(d: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(quantity, value, unit) rows of the first-order table from :func:`info_data`'s dict."""
    rows = [
        ("effective focal length f_E = 1/Phi", d["efl_mm"], "mm"),
        ("front / rear focal length f, f'", f"{format_value(d['front_focal_length_mm'])} / {format_value(d['rear_focal_length_mm'])}", "mm"),
        ("back focal length (last vertex to F')", d["bfl_mm"], "mm"),
        ("front focal length FFL (z of F)", d["ffl_mm"], "mm"),
        ("front / rear focal point z", f"{format_value(d['front_focal_z_mm'])} / {format_value(d['rear_focal_z_mm'])}", "mm"),
        ("front / rear principal point z", f"{format_value(d['front_principal_z_mm'])} / {format_value(d['rear_principal_z_mm'])}", "mm"),
        ("front / rear nodal point z", f"{format_value(d['front_nodal_z_mm'])} / {format_value(d['rear_nodal_z_mm'])}", "mm"),
        ("entrance pupil z / diameter", f"{format_value(d['entrance_pupil_z_mm'])} / {format_value(d['entrance_pupil_diameter_mm'])}", "mm"),
        ("exit pupil z / diameter", f"{format_value(d['exit_pupil_z_mm'])} / {format_value(d['exit_pupil_diameter_mm'])}", "mm"),
        ("pupil magnification mp = D_XP/D", d["pupil_magnification"], ""),
        ("s_EP (P to EP) / s'_XP (P' to XP)", f"{format_value(d['entrance_pupil_distance_mm'])} / {format_value(d['exit_pupil_distance_mm'])}", "mm"),
        ("f-number N = f/D", d["f_number"], ""),
        ("working f-number Nw = b N", d["working_f_number"], f"b = {d['bellows_factor']:.4f}"),
        ("paraxial image z / magnification", f"{format_value(d['image_z_mm'])} / {format_value(d['magnification'], '.6f')}", "mm"),
        ("image distance (last vertex to image)", d["image_distance_mm"], "mm"),
        ("unit-focus extension e", d["unit_focus_extension_mm"], "mm"),
        ("image surface (last vertex to it)", d["image_surface_distance_mm"], "mm"),
        ("overall length / total track", f"{format_value(d['overall_length_mm'])} / {format_value(d['total_track_mm'])}", "mm"),
        ("half field / paraxial image height", f"{format_value(d['half_field_deg'])} deg / {format_value(d['paraxial_image_height_mm'])}", "mm"),
        ("image height at each field", ", ".join(format_value(h) for h in d["field_image_heights_mm"]), "mm"),
        ("Lagrange invariant H", d["lagrange_invariant"], "mm"),
        ("Petzval sum (sum Phi/(n n'))", format_value(d["petzval_sum_per_mm"], ".6g"), "1/mm"),
    ]
    return [(a, format_value(b) if not isinstance(b, str) else b, c) for a, b, c in rows] + parabasal_rows(d)


def seidel_rows(lens, d: dict[str, Any]) -> list[list]:
    """Per-surface Seidel rows (``STO`` for the stop) and the ``SUM`` row, columns as :data:`SEIDEL_NAMES`."""
    from ..paraxial import SEIDEL_NAMES
    seidel = d["seidel"]
    per = seidel["per_surface_mm"]
    scale = max(abs(v) for k in SEIDEL_NAMES for v in per[k]) or 1.0
    srows = [[("STO" if i == lens.stop_index else str(i + 1))]
             + [per[k][i] if abs(per[k][i]) > 1e-12 * scale else 0.0 for k in SEIDEL_NAMES]
             for i in range(lens.n_surfaces)]
    srows.append(["SUM"] + [seidel[f"{k}_mm"] for k in SEIDEL_NAMES])
    return srows
