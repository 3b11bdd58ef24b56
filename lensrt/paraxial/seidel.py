"""Third-order (Seidel) aberration sums, per surface and total.

Convention (Welford, *Aberrations of Optical Systems*, ch. 7-8; Hopkins): with
the paraxial marginal ray (height y, slope u, full entrance pupil) and chief ray
(height y_bar, full field) of :func:`lensrt.paraxial.first_order.paraxial_rays`,
the refraction invariants A = n i = n (y c + u) and A_bar = n (y_bar c + u_bar),
the Lagrange invariant H = n (u_bar y - u y_bar) and Delta(x) = x' - x across a
surface, each surface contributes (lengths in mm)::

    S_I   = -A^2 y Delta(u/n)                       spherical
    S_II  = -A A_bar y Delta(u/n)                   coma
    S_III = -A_bar^2 y Delta(u/n)                   astigmatism
    S_IV  = -H^2 c Delta(1/n)  (= H^2 Phi / (n n'))   Petzval
    S_V   = -A_bar (A_bar^2 y Delta(1/n^2) - (H + A_bar y) y_bar c Delta(1/n))   distortion
    C_I   =  A y Delta(dn/n)                        axial colour
    C_II  =  A_bar y Delta(dn/n)                    lateral colour

with dn = n(short) - n(long) (by default the lens's shortest and longest
wavelengths, F and C lines for a one-wavelength lens). A conic or aspheric
surface adds, with G the r^4 coefficient of its sag minus that of the sphere of
its paraxial curvature, S_I* = 8 G (n' - n) y^4, S_II* = S_I* (y_bar/y),
S_III* = S_I* (y_bar/y)^2, S_V* = S_I* (y_bar/y)^3 (S_IV and the colour sums
are unchanged). An ideal paraxial lens (``TYPE PARAXIAL``) contributes nothing,
PTZ included: it images every plane perfectly onto its conjugate plane.

The wavefront coefficients (mm; divide by the wavelength for waves) are
W040 = S_I/8, W131 = S_II/2, W222 = S_III/2, W220 = (S_III + S_IV)/4,
W311 = S_V/2, W020 = C_I/2, W111 = C_II.

Mapping to CODE V's transverse third-order table (``tho``), verified digit for
digit on the CODE V double Gauss listing (tests/data/ag_dblgauss.lis), with n'
and u' the image-space index and marginal-ray slope (u' < 0 for a real image)::

    SA  = S_I / (2 n' u')               TCO = 3 S_II / (2 n' u')
    TAS = (3 S_III + S_IV) / (2 n' u')  SAS = (S_III + S_IV) / (2 n' u')
    PTB = S_IV / (2 n' u')              DST = S_V / (2 n' u')
    AX  = C_I / (n' u')                 LAT = C_II / (n' u')
    PTZ = -n' Phi / (n n')   (the surface's share of the Petzval curvature, 1/mm)

SA..LAT are transverse ray errors (mm) in the paraxial image plane at full
aperture and full field; AX and LAT are those of the short wavelength relative
to the long one. Distortion DST < 0 is barrel.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import LensrtError
from ..prescription.model import Lens
from ..prescription.shapes import profile_of, vertex_expansion
from ..units import FRAUNHOFER_NM
from .first_order import paraxial_rays
from .ynu import ParaxialSystem

__all__ = ["SeidelSums", "seidel_sums", "SEIDEL_NAMES", "CODEV_THO_COLUMNS"]

#: the seven sums, in the order of :meth:`SeidelSums.table`
SEIDEL_NAMES = ("spherical", "coma", "astigmatism", "petzval", "distortion", "axial_colour", "lateral_colour")
#: CODE V's ``tho`` columns, in its order
CODEV_THO_COLUMNS = ("SA", "TCO", "TAS", "SAS", "PTB", "DST", "AX", "LAT", "PTZ")


@dataclass(frozen=True)
class SeidelSums:
    """Seidel sums per surface (arrays of length n_surfaces, mm) and their totals.

    See the module docstring for the definitions and the CODE V mapping.
    """

    wavelength_nm: float
    short_nm: float
    long_nm: float
    lagrange_invariant: float
    image_index: float  # n' after the last surface
    image_marginal_slope: float  # u' of the marginal ray after the last surface
    spherical: np.ndarray  # S_I
    coma: np.ndarray  # S_II
    astigmatism: np.ndarray  # S_III
    petzval: np.ndarray  # S_IV
    distortion: np.ndarray  # S_V
    axial_colour: np.ndarray  # C_I
    lateral_colour: np.ndarray  # C_II
    petzval_curvature_per_mm: np.ndarray  # -n' Phi / (n n') per surface (CODE V PTZ)

    def table(self) -> np.ndarray:
        """(n_surfaces, 7) array of S_I..S_V, C_I, C_II (columns in :data:`SEIDEL_NAMES` order)."""
        return np.column_stack([getattr(self, k) for k in SEIDEL_NAMES])

    def totals(self) -> dict[str, float]:
        """The seven sums over all surfaces, keyed by :data:`SEIDEL_NAMES` (mm)."""
        return {k: float(np.sum(getattr(self, k))) for k in SEIDEL_NAMES}

    def to_dict(self) -> dict:
        """JSON-ready: totals with ``_mm`` keys and the per-surface lists."""
        return {**{f"{k}_mm": v for k, v in self.totals().items()},
                "per_surface_mm": {k: [float(x) for x in getattr(self, k)] for k in SEIDEL_NAMES},
                "short_nm": self.short_nm, "long_nm": self.long_nm}

    def transverse(self) -> dict[str, np.ndarray]:
        """CODE V's ``tho`` columns per surface: SA..LAT in mm, PTZ in 1/mm."""
        nu = self.image_index * self.image_marginal_slope
        if nu == 0.0:
            raise LensrtError("the image is at infinity: transverse aberrations are undefined (afocal)")
        k = 1.0 / (2.0 * nu)
        s1, s2, s3, s4, s5 = self.spherical, self.coma, self.astigmatism, self.petzval, self.distortion
        return {"SA": k * s1, "TCO": 3.0 * k * s2, "TAS": k * (3.0 * s3 + s4), "SAS": k * (s3 + s4),
                "PTB": k * s4, "DST": k * s5, "AX": self.axial_colour / nu, "LAT": self.lateral_colour / nu,
                "PTZ": self.petzval_curvature_per_mm.copy()}

    def transverse_totals(self) -> dict[str, float]:
        """Sums of :meth:`transverse` (CODE V's SUM row)."""
        return {k: float(np.sum(v)) for k, v in self.transverse().items()}

    def wavefront_mm(self) -> dict[str, float]:
        """Total wavefront coefficients W040, W131, W222, W220, W311, W020, W111 (mm)."""
        t = self.totals()
        return {"W040": t["spherical"] / 8.0, "W131": t["coma"] / 2.0, "W222": t["astigmatism"] / 2.0,
                "W220": (t["astigmatism"] + t["petzval"]) / 4.0, "W311": t["distortion"] / 2.0,
                "W020": t["axial_colour"] / 2.0, "W111": t["lateral_colour"]}


def _aspheric_g(lens: Lens, system: ParaxialSystem, i: int) -> float:
    """r^4 sag coefficient of surface i minus that of the sphere of its paraxial curvature."""
    s = lens.surfaces[i]
    if s.conic == 0.0 and not s.asphere and s.shape is None:
        return 0.0
    c_par = system.curvature_per_mm[i]
    if s.shape is not None:  # odd / Q-type / y-section of biconic and toroidal: the vertex Taylor series
        return vertex_expansion(profile_of(s))[1] - c_par ** 3 / 8.0
    c, k = s.curvature_per_mm, s.conic
    a4 = s.asphere[1] if len(s.asphere) > 1 else 0.0
    return (1.0 + k) * c ** 3 / 8.0 + a4 - c_par ** 3 / 8.0


def _default_colour_pair(lens: Lens) -> tuple[float, float]:
    nm = lens.wavelengths.nm
    if len(nm) > 1 and max(nm) > min(nm):
        return min(nm), max(nm)
    return FRAUNHOFER_NM["F"], FRAUNHOFER_NM["C"]


def seidel_sums(lens: Lens, wavelength_nm: float | None = None, object_distance_mm: float | None = None,
                field: float | None = None, short_nm: float | None = None,
                long_nm: float | None = None) -> SeidelSums:
    """Seidel sums of ``lens`` (module docstring).

    Parameters
    ----------
    lens : Lens
    wavelength_nm : float, optional
        Wavelength (nm) of the monochromatic sums; default the primary.
    object_distance_mm : float, optional
        Object to first vertex (mm, ``inf`` allowed); default the lens's own.
    field : float, optional
        Radial field of the chief ray, in the lens's field unit (rad or mm);
        default the largest field.
    short_nm, long_nm : float, optional
        Wavelengths (nm) of the colour sums, dn = n(short) - n(long); default
        the lens's extreme wavelengths (F and C lines for a single wavelength).
    """
    m, c, sysm = paraxial_rays(lens, wavelength_nm, object_distance_mm, field)
    if short_nm is None or long_nm is None:
        d_short, d_long = _default_colour_pair(lens)
        short_nm = d_short if short_nm is None else short_nm
        long_nm = d_long if long_nm is None else long_nm
    n = sysm.index
    dn = np.asarray(lens.indices(float(short_nm)) - lens.indices(float(long_nm)), dtype=np.float64)
    cv = sysm.curvature_per_mm
    H = float(n[0] * (c.u[0] * m.y[0] - m.u[0] * c.y[0]))
    N = sysm.n_surfaces
    y, yb = m.y[:N], c.y[:N]
    A, Ab = n[:-1] * m.i_angle, n[:-1] * c.i_angle
    d_u_n = m.u[1:] / n[1:] - m.u[:-1] / n[:-1]
    d_inv_n = 1.0 / n[1:] - 1.0 / n[:-1]
    d_inv_n2 = 1.0 / n[1:] ** 2 - 1.0 / n[:-1] ** 2
    s1 = -A * A * y * d_u_n
    s2 = -A * Ab * y * d_u_n
    s3 = -Ab * Ab * y * d_u_n
    s4 = -H * H * cv * d_inv_n
    s5 = -Ab * (Ab * Ab * d_inv_n2 * y - (H + Ab * y) * yb * cv * d_inv_n)
    d_dn_n = dn[1:] / n[1:] - dn[:-1] / n[:-1]
    c1 = A * y * d_dn_n
    c2 = Ab * y * d_dn_n
    # Conic and aspheric surfaces: the r^4 departure from the paraxial sphere (Welford, ch. 8).
    for i in range(N):
        g = _aspheric_g(lens, sysm, i)
        if g == 0.0:
            continue
        k8 = 8.0 * g * (n[i + 1] - n[i])
        s1[i] += k8 * y[i] ** 4
        s2[i] += k8 * y[i] ** 3 * yb[i]
        s3[i] += k8 * y[i] ** 2 * yb[i] ** 2
        s5[i] += k8 * y[i] * yb[i] ** 3
    ptz = -n[-1] * sysm.power_per_mm / (n[:-1] * n[1:])
    # an ideal paraxial lens images every plane onto its conjugate plane without aberration: no contribution
    ideal = np.array([sf.is_ideal for sf in lens.surfaces])
    for arr in (s1, s2, s3, s4, s5, c1, c2, ptz):
        arr[ideal] = 0.0
    if not all(math.isfinite(float(v)) for v in (s1.sum(), s2.sum(), s3.sum(), s5.sum())):
        raise LensrtError("the Seidel sums are not finite for this lens (a paraxial ray is undefined)")
    return SeidelSums(sysm.wavelength_nm, float(short_nm), float(long_nm), H, float(n[-1]), float(m.u[-1]),
                      s1, s2, s3, s4, s5, c1, c2, ptz)
