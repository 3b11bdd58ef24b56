"""The sensor's parameters and the quantities derived from them (gain, ISO, dynamic range).

Everything a photosite does to light is set by one frozen :class:`Sensor`. The chain and its
formulas (Field Guide to Photographic Science, pages as cited):

* photons -> electrons: QE_i(lambda) = FF eta T T_CFA,i (p. 40), full-well clipping;
* electrons -> voltage -> DN: conversion gain G_CG (uV/e-), programmable ISO gain G_ISO that
  doubles with every doubling of the ISO setting from the base ISO (p. 42), ADC gain G_ADC
  (DN/mV); the conversion factor g = 1 / (G_CG G_ISO G_ADC) in e-/DN, and the unity gain U is
  the ISO at which g = 1 (p. 43); an M-bit ADC with a bias offset (p. 43, p. 49);
* read noise split into the part upstream of the ISO amplifier (fixed in e-) and the part
  downstream (fixed in DN, so it falls in e- as G_ISO grows): above the ISO-less setting
  G_ISOless the camera applies further gain digitally, and read noise in e- stays flat (p. 50).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from ..errors import LensrtError
from ..units import LIGHT_SPEED_M_S, M2_PER_UM2, M_PER_NM, PLANCK_J_S
from .cfa import CFA
from .spectral import SpectralResponse, integration_weights_nm, ir_cut_transmission

__all__ = ["Sensor"]


@dataclass(frozen=True)
class Sensor:
    """A camera sensor: geometry, spectral response, noise, gain and ADC.

    Units are in the attribute names (e- = electrons, DN = data numbers).

    Attributes
    ----------
    name, description : str
    rows, cols : int
        Native resolution (photosites); a frame may be any size.
    pixel_pitch_um : float
        Photosite pitch p (um); the photosite area is A_p = p^2.
    fill_factor : float
        FF = A_det / A_p, effective (microlenses included), 0 < FF <= 1 (p. 40).
    response : SpectralResponse
        Relative eta T T_CFA,i curves (or absolute QE, see ``SpectralResponse.absolute``).
    peak_qe : tuple of 3 float
        Peak of eta T T_CFA,i for R, G, B (fraction), scales relative curves.
    ir_cut_nm : float or None
        50 % point of an extra IR-cut filter (nm); None when ``response`` already includes it.
    ir_cut_width_nm : float
        Edge width parameter of that filter (nm), see :func:`ir_cut_transmission`.
    cfa : CFA
    full_well_e : float
        Full-well capacity (e-), where the photosite clips.
    dark_current_e_per_s : float
        Mean dark current at the operating temperature (e-/s per photosite).
    dark_current_nonuniformity : float
        Relative spatial standard deviation of the dark current (fraction, part of DSNU, p. 47).
    read_noise_upstream_e : float
        Read noise arising before the ISO amplifier (e- rms), the same at every ISO (p. 50).
    read_noise_downstream_e : float
        Read noise arising after the ISO amplifier (ADC and later), referred to e- at base ISO
        (e- rms); in e- it falls as 1/G_ISO up to the ISO-less setting (p. 50).
    dsnu_e : float
        Dark signal non-uniformity: spatial standard deviation of the per-photosite offset (e-).
    prnu : float
        Photo-response non-uniformity: spatial standard deviation of the per-photosite gain
        (fraction, p. 47).
    conversion_gain_uv_per_e : float
        Conversion gain G_CG at the sense node (uV/e-).
    adc_gain_dn_per_mv : float
        ADC gain G_ADC (DN/mV) at base ISO.
    base_iso : float
        ISO setting with G_ISO = 1 (p. 42).
    iso_less_iso : float
        ISO setting above which extra gain is digital (G_ISOless, p. 50).
    max_iso : float
    adc_bits : int
        ADC bit depth M (p. 43); raw values run 0 .. 2^M - 1.
    bias_dn : float
        Bias offset added before quantisation (DN, p. 49), the raw black level.
    seed : int
        Seed of the fixed-pattern noise maps (DSNU, PRNU, dark-current map): the same sensor
        seed gives the same pattern.
    sources : dict
        Where each preset number comes from (parameter name -> text).
    """

    name: str
    rows: int
    cols: int
    pixel_pitch_um: float
    fill_factor: float
    response: SpectralResponse
    peak_qe: tuple[float, float, float]
    cfa: CFA
    full_well_e: float
    dark_current_e_per_s: float
    read_noise_upstream_e: float
    read_noise_downstream_e: float
    conversion_gain_uv_per_e: float
    adc_gain_dn_per_mv: float
    base_iso: float
    iso_less_iso: float
    adc_bits: int
    bias_dn: float
    dark_current_nonuniformity: float = 0.0
    dsnu_e: float = 0.0
    prnu: float = 0.0
    max_iso: float = 102400.0
    ir_cut_nm: float | None = None
    ir_cut_width_nm: float = 10.0
    seed: int = 0
    description: str = ""
    sources: dict = field(default_factory=dict, compare=False, hash=False)

    def __post_init__(self) -> None:
        checks = [("pixel_pitch_um", self.pixel_pitch_um > 0), ("fill_factor", 0 < self.fill_factor <= 1),
                  ("full_well_e", self.full_well_e > 0), ("dark_current_e_per_s", self.dark_current_e_per_s >= 0),
                  ("read_noise_upstream_e", self.read_noise_upstream_e >= 0),
                  ("read_noise_downstream_e", self.read_noise_downstream_e >= 0),
                  ("conversion_gain_uv_per_e", self.conversion_gain_uv_per_e > 0),
                  ("adc_gain_dn_per_mv", self.adc_gain_dn_per_mv > 0), ("base_iso", self.base_iso > 0),
                  ("iso_less_iso", self.iso_less_iso >= self.base_iso), ("max_iso", self.max_iso >= self.base_iso),
                  ("adc_bits", 1 <= int(self.adc_bits) <= 16), ("bias_dn", 0 <= self.bias_dn < 2 ** self.adc_bits),
                  ("dsnu_e", self.dsnu_e >= 0), ("prnu", 0 <= self.prnu < 0.5),
                  ("dark_current_nonuniformity", 0 <= self.dark_current_nonuniformity < 1),
                  ("rows", self.rows > 0), ("cols", self.cols > 0),
                  ("peak_qe", len(self.peak_qe) == 3 and all(0 < q <= 1 for q in self.peak_qe))]
        for name, ok in checks:
            if not ok:
                raise LensrtError(f"sensor {self.name!r}: {name} = {getattr(self, name)!r} is out of range",
                                  hint="see the Sensor docstring for units and ranges")

    # --- gain and ISO (p. 42-43, p. 50) ------------------------------------------------
    @property
    def g_base_e_per_dn(self) -> float:
        """Conversion factor g at base ISO (e-/DN): 1 / (G_CG G_ADC) (p. 43)."""
        return 1.0 / (self.conversion_gain_uv_per_e * 1e-3 * self.adc_gain_dn_per_mv)

    def check_iso(self, iso: float) -> float:
        if not (self.base_iso <= iso <= self.max_iso) or not math.isfinite(iso):
            raise LensrtError(f"ISO {iso:g} is outside {self.base_iso:g}..{self.max_iso:g} for sensor {self.name!r}")
        return float(iso)

    def analog_gain(self, iso: float) -> float:
        """Programmable (analog) ISO gain G_ISO: doubles per ISO doubling up to the ISO-less setting."""
        return min(self.check_iso(iso), self.iso_less_iso) / self.base_iso

    def digital_gain(self, iso: float) -> float:
        """Gain applied digitally above the ISO-less setting (1 below it)."""
        return max(self.check_iso(iso) / self.iso_less_iso, 1.0)

    def g_e_per_dn(self, iso: float) -> float:
        """Conversion factor g (e-/DN) at ``iso``: g_base * base_iso / iso (p. 42-43)."""
        return self.g_base_e_per_dn / (self.analog_gain(iso) * self.digital_gain(iso))

    @property
    def unity_gain_iso(self) -> float:
        """ISO at which g = 1 e-/DN, the unity gain U (p. 43)."""
        return self.base_iso * self.g_base_e_per_dn

    @property
    def adc_max_dn(self) -> int:
        """Largest raw value, 2^M - 1."""
        return 2 ** int(self.adc_bits) - 1

    def white_level_dn(self, iso: float) -> float:
        """Raw clipping point (DN): the ADC's top, or the full well if that comes first."""
        return float(min(self.adc_max_dn, self.bias_dn + math.floor(self.full_well_e / self.g_e_per_dn(iso))))

    def read_noise_e(self, iso: float) -> float:
        """Total read noise referred to e- at ``iso`` (p. 50): sqrt(up^2 + (down / G_ISO)^2)."""
        return math.hypot(self.read_noise_upstream_e, self.read_noise_downstream_e / self.analog_gain(iso))

    def read_noise_dn(self, iso: float) -> float:
        """Total read noise in DN at ``iso`` (before quantisation)."""
        return self.read_noise_e(iso) / self.g_e_per_dn(iso)

    def raw_dynamic_range_stops(self, iso: float) -> float:
        """Raw dynamic range log2(n_DN,clip / sigma_DN,read) in stops (p. 51); n_DN,clip above bias."""
        return math.log2((self.white_level_dn(iso) - self.bias_dn) / self.read_noise_dn(iso))

    # --- spectral response (p. 40) ------------------------------------------------------
    @property
    def photosite_area_m2(self) -> float:
        return self.pixel_pitch_um ** 2 * M2_PER_UM2

    def qe(self, wavelength_nm: np.ndarray) -> np.ndarray:
        """Quantum efficiency QE_i(lambda) = FF eta T T_CFA,i (p. 40), shape (n, 3), fraction."""
        w = np.asarray(wavelength_nm, dtype=np.float64)
        q = self.response.at(w)
        if not self.response.absolute:
            q = q * np.asarray(self.peak_qe)
        if self.ir_cut_nm is not None:
            q = q * ir_cut_transmission(w, self.ir_cut_nm, self.ir_cut_width_nm)[:, None]
        return self.fill_factor * q

    def electron_weights(self, wavelength_nm: np.ndarray, bin_width_nm: np.ndarray | float | None = None) -> np.ndarray:
        """Matrix W (n, 3) with electrons_i per second = sum_k E(lambda_k) W[k, i].

        n_e,i = t A_p sum_k (lambda_k / hc) QE_i(lambda_k) E_lambda(lambda_k) d lambda_k
        (p. 40: n_ph = (lambda / hc) A E_lambda t integrated over the passband; the fill factor
        sits inside QE, so the area is the whole photosite's). E in W / (m^2 nm).
        """
        w = np.asarray(wavelength_nm, dtype=np.float64)
        dl = integration_weights_nm(w, bin_width_nm)
        photons_per_joule = w * M_PER_NM / (PLANCK_J_S * LIGHT_SPEED_M_S)
        return (photons_per_joule * dl * self.photosite_area_m2)[:, None] * self.qe(w)

    # --- presentation ---------------------------------------------------------------------
    def summary(self, isos: tuple[float, ...] | None = None) -> dict[str, Any]:
        """Parameters and derived numbers as a JSON-ready dict."""
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "response":
                out["response"] = v.source
            elif f.name == "cfa":
                out["cfa"] = v.name
            elif f.name == "peak_qe":
                out["peak_qe"] = list(v)
            else:
                out[f.name] = v
        if isos is None:
            isos = tuple(i for i in (self.base_iso * 2 ** k for k in range(0, 12)) if i <= self.max_iso)
        out["derived"] = {
            "megapixels": self.rows * self.cols / 1e6,
            "sensor_width_mm": self.cols * self.pixel_pitch_um / 1000, "sensor_height_mm": self.rows * self.pixel_pitch_um / 1000,
            "g_base_e_per_dn": self.g_base_e_per_dn, "unity_gain_iso": self.unity_gain_iso,
            "per_iso": [{"iso": i, "g_e_per_dn": self.g_e_per_dn(i), "read_noise_e": self.read_noise_e(i),
                         "read_noise_dn": self.read_noise_dn(i), "white_level_dn": self.white_level_dn(i),
                         "raw_dynamic_range_stops": self.raw_dynamic_range_stops(i)} for i in isos],
        }
        return out

