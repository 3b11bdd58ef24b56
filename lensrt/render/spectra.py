"""Spectra on a wavelength grid: illuminants, photometry, CIE XYZ / sRGB, wavelength sampling.

A scene's spectra are arrays sampled on one uniform :class:`WavelengthGrid`
(default 380-780 nm in 5 nm steps), wavelength axis last. Between grid points
a spectrum is the linear interpolant, and every integral over wavelength here
is the trapezoid rule over the grid -- exactly what a Monte Carlo estimate
with wavelengths drawn over ``[min_nm, max_nm]`` converges to.

Data come from colour-science: the CIE illuminants (D-series, A, FL-series,
LED-series, HP-series), Planck's law, the CIE 1931 2-degree colour-matching
functions, the CIE 1924 photopic luminous efficiency V(lambda), the
ColorChecker reflectances and the sRGB matrices.

Radiometry (Field Guide p. 39-40): a luminance L_v (cd/m^2) and a spectral
radiance L_e(lambda) (W / (m^2 sr nm)) are tied by
``L_v = K_m * int L_e(lambda) V(lambda) dlambda`` with K_m = 683 lm/W
(:data:`lensrt.units.LUMINOUS_EFFICACY_LM_PER_W`); the same holds for
illuminance (lux) and spectral irradiance (W / (m^2 nm)), and for luminous
intensity (cd) and spectral radiant intensity (W / (sr nm)).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import LensrtError
from ..units import LUMINOUS_EFFICACY_LM_PER_W

__all__ = [
    "WavelengthGrid", "DEFAULT_GRID", "illuminant_names", "illuminant", "blackbody_radiance",
    "photopic_v", "cie_xyz_cmfs", "integrate", "luminous_value", "scale_to_luminous",
    "spectral_to_xyz", "reflectance_to_xyz", "xyz_to_linear_srgb", "linear_srgb_to_xyz",
    "srgb_decode", "srgb_encode", "mallett2019_basis", "linear_rgb_to_reflectance",
    "colorchecker_names", "colorchecker_reflectances", "WavelengthSampler",
]


@dataclass(frozen=True)
class WavelengthGrid:
    """A uniform wavelength grid, ``min_nm`` to ``max_nm`` inclusive in steps of ``step_nm``."""

    min_nm: float = 380.0
    max_nm: float = 780.0
    step_nm: float = 5.0

    def __post_init__(self) -> None:
        lo, hi, st = float(self.min_nm), float(self.max_nm), float(self.step_nm)
        if not (200.0 <= lo < hi <= 2000.0):
            raise LensrtError(f"wavelength range {lo:g}-{hi:g} nm is not an increasing range within 200-2000 nm")
        if not st > 0.0:
            raise LensrtError(f"wavelength step {st:g} nm must be positive")
        n = (hi - lo) / st
        if abs(n - round(n)) > 1e-6 or round(n) < 1:
            raise LensrtError(f"wavelength step {st:g} nm does not divide the range {lo:g}-{hi:g} nm",
                              hint="choose a step that divides max_nm - min_nm")

    @property
    def n(self) -> int:
        """Number of grid points."""
        return int(round((self.max_nm - self.min_nm) / self.step_nm)) + 1

    @property
    def nm(self) -> np.ndarray:
        """The grid's wavelengths (nm), float64."""
        return self.min_nm + self.step_nm * np.arange(self.n, dtype=np.float64)

    @property
    def weights_nm(self) -> np.ndarray:
        """Trapezoid weights (nm): ``integral f dlambda = sum(f * weights_nm)``."""
        w = np.full(self.n, self.step_nm)
        w[0] = w[-1] = 0.5 * self.step_nm
        return w

    def shape(self):  # -> colour.SpectralShape
        import colour
        return colour.SpectralShape(self.min_nm, self.max_nm, self.step_nm)

    def interp(self, values: np.ndarray, wavelength_nm: np.ndarray | float) -> np.ndarray:
        """Linear interpolant of grid ``values`` (wavelength axis last) at ``wavelength_nm``; 0 outside."""
        v = np.asarray(values, dtype=np.float64)
        w = np.asarray(wavelength_nm, dtype=np.float64)
        if v.ndim == 1:
            return np.interp(w, self.nm, v, left=0.0, right=0.0)
        return np.stack([np.interp(w, self.nm, row, left=0.0, right=0.0)
                         for row in v.reshape(-1, self.n)]).reshape(v.shape[:-1] + np.shape(w))


DEFAULT_GRID = WavelengthGrid()


def _resample(wavelength_nm: np.ndarray, values: np.ndarray, grid: WavelengthGrid, hold_edges: bool) -> np.ndarray:
    """Tabulated data -> grid, linear interpolation; outside the data: 0, or the edge value."""
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    if hold_edges:
        return np.interp(grid.nm, wl, v)
    return np.interp(grid.nm, wl, v, left=0.0, right=0.0)


def _sd_on_grid(sd, grid: WavelengthGrid, hold_edges: bool = False) -> np.ndarray:
    """A colour-science SpectralDistribution sampled on ``grid`` (linear between its samples)."""
    return _resample(sd.wavelengths, sd.values, grid, hold_edges)


#: aliases accepted for colour-science illuminant names
_ALIASES = {f"F{i}": f"FL{i}" for i in range(1, 13)}


@lru_cache(maxsize=1)
def illuminant_names() -> tuple[str, ...]:
    """Names of the CIE illuminants colour-science ships (D65, A, FL1-FL12, LED-B1 ..., HP1 ...)."""
    import colour
    return tuple(colour.SDS_ILLUMINANTS.keys())


def illuminant(name: str, grid: WavelengthGrid = DEFAULT_GRID) -> np.ndarray:
    """Relative spectral power of a CIE illuminant on ``grid`` (as tabulated: D65 is 100 at 560 nm).

    ``F1`` ... ``F12`` are accepted for ``FL1`` ... ``FL12``; ``E`` is the
    equal-energy illuminant. Zero outside the tabulated range.
    """
    import colour
    key = _ALIASES.get(name, name)
    if key not in colour.SDS_ILLUMINANTS:
        matches = [k for k in illuminant_names() if k.lower() == key.lower()]
        if not matches:
            import difflib
            close = difflib.get_close_matches(key, illuminant_names(), n=3)
            raise LensrtError(f"unknown illuminant {name!r}",
                              hint=("did you mean " + ", ".join(close) + "?") if close else
                              "use D65, A, FL1-FL12, LED-B1..LED-V2, HP1-HP5 or blackbody_K = <kelvin>")
        key = matches[0]
    return _sd_on_grid(colour.SDS_ILLUMINANTS[key], grid)


def blackbody_radiance(temperature_k: float, grid: WavelengthGrid = DEFAULT_GRID) -> np.ndarray:
    """Planck spectral radiance of a blackbody, W / (m^2 sr nm), on ``grid`` (colour-science, n = 1)."""
    import colour
    t = float(temperature_k)
    if not 100.0 <= t <= 1.0e5:
        raise LensrtError(f"blackbody temperature {t:g} K is outside 100-100000 K")
    # colour.planck_law takes metres and returns W / (sr m^2 m); sd_blackbody returns per nm.
    return np.asarray(colour.sd_blackbody(t, grid.shape()).values, dtype=np.float64)


@lru_cache(maxsize=8)
def _v_cached(grid: WavelengthGrid) -> np.ndarray:
    import colour
    return _sd_on_grid(colour.SDS_LEFS["CIE 1924 Photopic Standard Observer"], grid)


def photopic_v(grid: WavelengthGrid = DEFAULT_GRID) -> np.ndarray:
    """CIE 1924 photopic luminous efficiency V(lambda) on ``grid`` (0 outside 360-830 nm)."""
    return _v_cached(grid).copy()


@lru_cache(maxsize=8)
def _cmfs_cached(grid: WavelengthGrid) -> np.ndarray:
    import colour
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return np.stack([_resample(cmfs.wavelengths, cmfs.values[:, i], grid, False) for i in range(3)])


def cie_xyz_cmfs(grid: WavelengthGrid = DEFAULT_GRID) -> np.ndarray:
    """CIE 1931 2-degree colour-matching functions x, y, z on ``grid``, shape (3, n)."""
    return _cmfs_cached(grid).copy()


def integrate(values: np.ndarray, grid: WavelengthGrid) -> np.ndarray:
    """Trapezoid integral over wavelength (last axis) of grid-sampled ``values``; result times nm."""
    v = np.asarray(values, dtype=np.float64)
    if v.shape[-1] != grid.n:
        raise ValueError(f"spectrum has {v.shape[-1]} samples, the grid {grid.n}")
    return v @ grid.weights_nm


def luminous_value(values: np.ndarray, grid: WavelengthGrid) -> np.ndarray:
    """Photometric value K_m int S V dlambda of a radiometric spectrum S.

    Spectral radiance W/(m^2 sr nm) -> cd/m^2; irradiance W/(m^2 nm) -> lux;
    radiant intensity W/(sr nm) -> cd; spectral flux W/nm -> lm.
    """
    return LUMINOUS_EFFICACY_LM_PER_W * integrate(np.asarray(values) * photopic_v(grid), grid)


def scale_to_luminous(relative: np.ndarray, target: float, grid: WavelengthGrid, what: str = "spectrum") -> np.ndarray:
    """Scale a relative spectrum so that its photometric value (see :func:`luminous_value`) is ``target``."""
    lv = float(luminous_value(relative, grid))
    if not lv > 0.0:
        raise LensrtError(f"{what} has no power where the eye sees (K_m int S V dlambda = 0), "
                          "so a luminous value cannot set its scale",
                          hint="use radiance_scale (W / (m^2 sr nm) per unit of the spectrum) instead")
    return np.asarray(relative, dtype=np.float64) * (float(target) / lv)


def spectral_to_xyz(values: np.ndarray, grid: WavelengthGrid, absolute: bool = True) -> np.ndarray:
    """CIE 1931 XYZ of spectra (wavelength axis last).

    ``absolute``: X, Y, Z = K_m int S (x, y, z) dlambda, so Y is the luminance
    (cd/m^2) of a radiance, the illuminance (lux) of an irradiance. Otherwise
    the plain integrals int S (x, y, z) dlambda.
    """
    k = LUMINOUS_EFFICACY_LM_PER_W if absolute else 1.0
    cmfs = cie_xyz_cmfs(grid) * grid.weights_nm
    return k * np.asarray(values, dtype=np.float64) @ cmfs.T


def reflectance_to_xyz(reflectance: np.ndarray, illuminant_values: np.ndarray, grid: WavelengthGrid) -> np.ndarray:
    """XYZ of a reflectance under an illuminant, normalised so the perfect white has Y = 100 (CIE 15)."""
    illum = np.asarray(illuminant_values, dtype=np.float64)
    xyz = spectral_to_xyz(np.asarray(reflectance, dtype=np.float64) * illum, grid, absolute=False)
    y_white = spectral_to_xyz(illum, grid, absolute=False)[1]
    return 100.0 * xyz / y_white


@lru_cache(maxsize=1)
def _srgb_matrices() -> tuple[np.ndarray, np.ndarray]:
    import colour
    cs = colour.RGB_COLOURSPACES["sRGB"]
    return np.asarray(cs.matrix_XYZ_to_RGB, dtype=np.float64), np.asarray(cs.matrix_RGB_to_XYZ, dtype=np.float64)


def xyz_to_linear_srgb(xyz: np.ndarray) -> np.ndarray:
    """XYZ (last axis) -> linear sRGB (IEC 61966-2-1 matrix, D65 white, no adaptation)."""
    return np.asarray(xyz, dtype=np.float64) @ _srgb_matrices()[0].T


def linear_srgb_to_xyz(rgb: np.ndarray) -> np.ndarray:
    """Linear sRGB (last axis) -> XYZ."""
    return np.asarray(rgb, dtype=np.float64) @ _srgb_matrices()[1].T


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] -> linear (the IEC 61966-2-1 EOTF, via colour-science)."""
    import colour
    return np.asarray(colour.models.eotf_sRGB(np.asarray(encoded, dtype=np.float64)), dtype=np.float64)


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Linear values -> sRGB-encoded (inverse EOTF), clipped to [0, 1] first."""
    import colour
    return np.asarray(colour.models.eotf_inverse_sRGB(np.clip(linear, 0.0, 1.0)), dtype=np.float64)


@lru_cache(maxsize=8)
def _mallett_cached(grid: WavelengthGrid) -> np.ndarray:
    import colour
    basis = colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019
    return np.stack([_resample(basis.wavelengths, basis.values[:, i], grid, True) for i in range(3)])


def mallett2019_basis(grid: WavelengthGrid = DEFAULT_GRID) -> np.ndarray:
    """Mallett & Yuksel (2019) sRGB reflectance basis on ``grid``, shape (3, n), rows r, g, b.

    A linear sRGB colour (r, g, b) in [0, 1] becomes the reflectance
    ``r B_r + g B_g + b B_b``: non-negative, at most 1 (the three curves sum to
    1 at every wavelength), and it reproduces (r, g, b) under D65. Edge values
    are held outside 380-780 nm, where the basis is tabulated.
    """
    return _mallett_cached(grid).copy()


def linear_rgb_to_reflectance(rgb: np.ndarray, grid: WavelengthGrid = DEFAULT_GRID) -> np.ndarray:
    """Spectral reflectance of linear sRGB colours (last axis, clipped to [0, 1]) by Mallett-Yuksel 2019."""
    c = np.clip(np.asarray(rgb, dtype=np.float64), 0.0, 1.0)
    return c @ mallett2019_basis(grid)


def colorchecker_names(chart: str = "ColorChecker N Ohta") -> tuple[str, ...]:
    """Patch names of a colour-science ColorChecker, row by row from the top left (dark skin)."""
    import colour
    if chart not in colour.SDS_COLOURCHECKERS:
        raise LensrtError(f"unknown ColorChecker data set {chart!r}",
                          hint="use one of " + ", ".join(repr(k) for k in colour.SDS_COLOURCHECKERS))
    return tuple(colour.SDS_COLOURCHECKERS[chart].keys())


def colorchecker_reflectances(chart: str = "ColorChecker N Ohta", grid: WavelengthGrid = DEFAULT_GRID) -> np.ndarray:
    """The 24 patch reflectances of a ColorChecker data set on ``grid``, shape (24, n); edges held."""
    import colour
    names = colorchecker_names(chart)
    sds = colour.SDS_COLOURCHECKERS[chart]
    return np.stack([_sd_on_grid(sds[k], grid, hold_edges=True) for k in names])


@dataclass(frozen=True)
class WavelengthSampler:
    """Piecewise-constant importance sampling of wavelengths over the grid's intervals.

    Interval i = [nm[i], nm[i+1]] has probability ``p[i]``; inside an interval
    the wavelength is uniform, so pdf(lambda) = p[i] / step_nm. ``cdf`` has
    n_intervals + 1 entries from 0 to 1 (what the kernel's binary search uses).
    """

    grid: WavelengthGrid
    cdf: np.ndarray
    label: str = "uniform"

    @classmethod
    def uniform(cls, grid: WavelengthGrid) -> "WavelengthSampler":
        m = grid.n - 1
        return cls(grid, np.linspace(0.0, 1.0, m + 1), "uniform")

    @classmethod
    def from_weight(cls, grid: WavelengthGrid, weight: np.ndarray, uniform_fraction: float = 0.1,
                    label: str = "weighted") -> "WavelengthSampler":
        """Sample in proportion to a non-negative ``weight`` on the grid, mixed with a uniform part.

        The uniform part (``uniform_fraction``, default 10 %) keeps the pdf
        positive wherever the integrand may be non-zero (defensive sampling).
        """
        w = np.asarray(weight, dtype=np.float64)
        if w.shape != (grid.n,) or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise LensrtError("a wavelength sampling weight must be finite, non-negative, one value per grid point")
        if not 0.0 <= uniform_fraction <= 1.0:
            raise LensrtError(f"uniform fraction {uniform_fraction:g} is not within [0, 1]")
        mass = 0.5 * (w[:-1] + w[1:])
        total = mass.sum()
        m = grid.n - 1
        p = np.full(m, 1.0 / m) if total <= 0 else (1.0 - uniform_fraction) * mass / total + uniform_fraction / m
        cdf = np.concatenate([[0.0], np.cumsum(p)])
        cdf /= cdf[-1]
        return cls(grid, cdf, label)

    @property
    def probabilities(self) -> np.ndarray:
        """Probability of each grid interval."""
        return np.diff(self.cdf)

    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Wavelengths (nm) and their pdf (1/nm) for uniform numbers ``u`` in [0, 1)."""
        u = np.asarray(u, dtype=np.float64)
        p = self.probabilities
        i = np.clip(np.searchsorted(self.cdf, u, side="right") - 1, 0, len(p) - 1)
        frac = np.where(p[i] > 0, (u - self.cdf[i]) / np.where(p[i] > 0, p[i], 1.0), 0.5)
        lam = self.grid.min_nm + (i + np.clip(frac, 0.0, 1.0)) * self.grid.step_nm
        return lam, p[i] / self.grid.step_nm

    def pdf(self, wavelength_nm: np.ndarray) -> np.ndarray:
        """pdf (1/nm) at ``wavelength_nm``; 0 outside the grid's range."""
        lam = np.asarray(wavelength_nm, dtype=np.float64)
        p = self.probabilities
        i = np.clip(np.floor((lam - self.grid.min_nm) / self.grid.step_nm).astype(int), 0, len(p) - 1)
        inside = (lam >= self.grid.min_nm) & (lam <= self.grid.max_nm)
        return np.where(inside, p[i] / self.grid.step_nm, 0.0)
