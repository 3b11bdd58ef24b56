"""EMVA 1288 photon-transfer characterisation: simulate the measurement, analyse it as the standard does.

Measurement (EMVA 1288 Release 4.0, linear sensors): a uniform monochromatic field at
wavelength lambda, constant exposure time, irradiance stepped in equal increments from dark to
beyond saturation; at each step two frames A and B; a dark pair; a stack of L dark frames and
of L frames near 50 % saturation for the spatial (fixed-pattern) non-uniformities. For a
colour sensor one CFA channel is analysed (its photosites only).

Analysis, per step: mu_y = mean of (A + B) / 2, sigma_y^2 = var(A - B) / 2 (temporal).

* photon transfer: sigma_y^2 - sigma_y.dark^2 = K (mu_y - mu_y.dark), K the system gain (DN/e-),
  fitted up to 70 % of saturation; K = 1 / g of the Field Guide (p. 43);
* responsivity R = (mu_y - mu_y.dark) / mu_p; quantum efficiency eta = R / K, with
  mu_p = A t lambda E / (hc) photons on the photosite area A;
* saturation: the step of maximum temporal variance; mu_e.sat = eta mu_p.sat;
* temporal dark noise sigma_d = sqrt(sigma_y.dark^2 - 1/12) / K (e-; 1/12 DN^2 quantisation);
* absolute sensitivity threshold mu_p.min = (sigma_y.dark / K + 1/2) / eta;
  dynamic range DR = mu_p.sat / mu_p.min;
* SNR = (mu_y - mu_y.dark) / sigma_y; its maximum is taken at saturation;
* DSNU = s_y.dark / K (e-), PRNU = sqrt(s_y.50^2 - s_y.dark^2) / (mu_y.50 - mu_y.dark), with the
  spatial variances s^2 of the L-frame averages corrected for their residual temporal
  variance sigma^2 / L.

The Field Guide's two-frame method (p. 48) regresses the same pair variance on the
bias-subtracted mean without the dark correction: slope 1 / g, intercept the read noise
variance; :func:`two_frame_gain` implements it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import LensrtError
from ..units import LIGHT_SPEED_M_S, M_PER_NM, PLANCK_J_S
from .detector import electrons_to_raw, mean_photoelectrons
from .model import Sensor

__all__ = ["EmvaData", "EmvaResult", "simulate_emva", "analyse_emva", "expected_emva", "two_frame_gain",
           "characterize"]


@dataclass
class EmvaData:
    """Statistics of a simulated EMVA 1288 measurement (one channel).

    ``mu_p`` photons per photosite per step; ``mu_y``, ``var_y`` mean and temporal variance
    (DN, DN^2) per step; ``mu_y_dark``, ``var_y_dark`` of the dark pair; ``dark_stack_mean`` and
    ``bright_stack_mean``: L-frame averages (channel photosites only, flattened) for DSNU and PRNU,
    ``var_y_bright``/``mu_p_bright`` the temporal variance and photons of that bright stack.
    """

    wavelength_nm: float
    exposure_s: float
    iso: float
    channel: int
    bias_dn: float
    mu_p: np.ndarray
    mu_y: np.ndarray
    var_y: np.ndarray
    mu_y_dark: float
    var_y_dark: float
    dark_stack_mean: np.ndarray
    bright_stack_mean: np.ndarray
    var_y_bright: float
    mu_p_bright: float
    n_stack: int
    n_pixels: int
    seconds: float = 0.0


@dataclass
class EmvaResult:
    """EMVA 1288 results (units in the names), with the standard error of K from the fit."""

    system_gain_dn_per_e: float
    system_gain_stderr: float
    g_e_per_dn: float
    quantum_efficiency: float
    temporal_dark_noise_e: float
    saturation_capacity_e: float
    saturation_photons: float
    sensitivity_threshold_photons: float
    dynamic_range_db: float
    dynamic_range_stops: float
    snr_max_db: float
    dsnu_e: float
    prnu_percent: float
    two_frame_g_e_per_dn: float
    two_frame_read_noise_dn: float
    linearity_error_percent: float
    dark_noise_quantization_limited: bool
    snr_curve: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _channel_pixels(sensor: Sensor, shape: tuple[int, int], channel: int) -> np.ndarray:
    cmap = sensor.cfa.channel_map(*shape)
    mask = cmap == channel
    if not mask.any():
        raise LensrtError(f"channel {channel} does not occur in the CFA")
    return mask


def simulate_emva(sensor: Sensor, *, rng: np.random.Generator, iso: float | None = None, wavelength_nm: float = 540.0,
                  exposure_s: float = 0.01, n_levels: int = 40, shape: tuple[int, int] = (256, 256),
                  channel: int = 1, n_stack: int = 16, overexpose: float = 1.2) -> EmvaData:
    """Simulate the EMVA 1288 measurement on ``sensor`` (see the module docstring).

    Parameters
    ----------
    wavelength_nm : float
        Wavelength of the monochromatic light (nm).
    exposure_s : float
        Constant exposure time (s); irradiance is stepped.
    n_levels : int
        Irradiance steps from 0 to ``overexpose`` x the saturation irradiance (EMVA asks >= 50
        in a full measurement; 20-40 suffice for the fits here).
    shape : (rows, cols)
        Frame size (photosites).
    channel : int
        CFA channel analysed (0 R, 1 G, 2 B).
    n_stack : int
        L, frames averaged for DSNU and PRNU.
    """
    import time
    t0 = time.perf_counter()
    iso = sensor.base_iso if iso is None else sensor.check_iso(iso)
    if n_levels < 8:
        raise LensrtError("EMVA characterisation needs at least 8 irradiance levels")
    mask = _channel_pixels(sensor, shape, channel)
    wl = np.array([float(wavelength_nm)])
    # electrons of the channel per unit irradiance (W/m^2 in a 1 nm band), mean over its photosites
    e_per_E = float(mean_photoelectrons(sensor, np.ones(1), wl, exposure_s, bin_width_nm=1.0, shape=shape)[mask].mean())
    if e_per_E <= 0:
        raise LensrtError(f"channel {'RGB'[channel]} has no response at {wavelength_nm:g} nm")
    photons_per_E = wl[0] * M_PER_NM / (PLANCK_J_S * LIGHT_SPEED_M_S) * sensor.photosite_area_m2 * exposure_s
    clip_e = min(sensor.full_well_e, (sensor.adc_max_dn - sensor.bias_dn) * sensor.g_e_per_dn(iso))
    E_levels = np.linspace(0.0, overexpose * clip_e / e_per_E, n_levels)

    def pair(E: float) -> tuple[np.ndarray, np.ndarray]:
        mean_e = mean_photoelectrons(sensor, np.array([E]), wl, exposure_s, bin_width_nm=1.0, shape=shape)
        a = electrons_to_raw(sensor, mean_e, exposure_s, rng=rng, iso=iso).dn[mask].astype(np.float64)
        b = electrons_to_raw(sensor, mean_e, exposure_s, rng=rng, iso=iso).dn[mask].astype(np.float64)
        return a, b

    mu_y, var_y = [], []
    for E in E_levels[1:]:
        a, b = pair(E)
        mu_y.append(0.5 * (a.mean() + b.mean()))
        var_y.append(0.5 * np.var(a - b))
    da, db = pair(0.0)
    mu_dark, var_dark = 0.5 * (da.mean() + db.mean()), 0.5 * np.var(da - db)

    def stack(E: float) -> np.ndarray:
        mean_e = mean_photoelectrons(sensor, np.array([E]), wl, exposure_s, bin_width_nm=1.0, shape=shape)
        acc = np.zeros(int(mask.sum()))
        for _ in range(n_stack):
            acc += electrons_to_raw(sensor, mean_e, exposure_s, rng=rng, iso=iso).dn[mask]
        return acc / n_stack

    E50 = 0.5 * clip_e / e_per_E
    a50, b50 = pair(E50)
    return EmvaData(wavelength_nm=float(wavelength_nm), exposure_s=exposure_s, iso=float(iso), channel=channel,
                    bias_dn=float(sensor.bias_dn), mu_p=E_levels[1:] * photons_per_E, mu_y=np.array(mu_y),
                    var_y=np.array(var_y), mu_y_dark=float(mu_dark), var_y_dark=float(var_dark),
                    dark_stack_mean=stack(0.0), bright_stack_mean=stack(E50), var_y_bright=float(0.5 * np.var(a50 - b50)),
                    mu_p_bright=E50 * photons_per_E, n_stack=n_stack, n_pixels=int(mask.sum()),
                    seconds=time.perf_counter() - t0)


def _linfit(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Least-squares line y = a + b x: (b, a, standard error of b)."""
    A = np.stack([np.ones_like(x), x], axis=1)
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    resid = y - A @ coef
    dof = max(1, x.size - 2)
    s2 = float(resid @ resid) / dof
    cov = s2 * np.linalg.inv(A.T @ A)
    return float(coef[1]), float(coef[0]), float(math.sqrt(cov[1, 1]))


def two_frame_gain(mean_dn: np.ndarray, var_dn2: np.ndarray) -> tuple[float, float]:
    """Field Guide p. 48: regress pair variance on bias-subtracted mean; returns (g in e-/DN, read noise in DN).

    ``var = mean / g + sigma_read^2`` for a shot-noise + read-noise sensor.
    """
    slope, intercept, _ = _linfit(np.asarray(mean_dn, float), np.asarray(var_dn2, float))
    if slope <= 0:
        raise LensrtError("variance does not grow with the mean; no gain can be found")
    return 1.0 / slope, math.sqrt(max(intercept, 0.0))


def analyse_emva(d: EmvaData) -> EmvaResult:
    """EMVA 1288 analysis of ``d`` (see the module docstring)."""
    sig = d.mu_y - d.mu_y_dark
    tvar = d.var_y - d.var_y_dark
    i_sat = int(np.argmax(d.var_y))
    mu_sat = sig[i_sat]
    fit = (sig > 0) & (sig <= 0.7 * mu_sat) & (np.arange(sig.size) < i_sat)
    if fit.sum() < 4:
        raise LensrtError("too few levels below 70 % of saturation; use more levels")
    K, _, K_se = _linfit(sig[fit], tvar[fit])
    R, r0, _ = _linfit(d.mu_p[fit], sig[fit])
    eta = R / K
    # linearity error (EMVA): deviation of mean signal from the regression, 5-95 % of saturation
    lin = (sig >= 0.05 * mu_sat) & (sig <= 0.95 * mu_sat)
    b, a, _ = _linfit(d.mu_p[lin], sig[lin])
    dev = (sig[lin] - (a + b * d.mu_p[lin])) / (a + b * d.mu_p[lin])
    lin_err = 50.0 * (dev.max() - dev.min())
    sigma_d = math.sqrt(max(d.var_y_dark - 1.0 / 12.0, 0.0)) / K
    mu_p_sat = float(d.mu_p[i_sat])
    mu_p_min = (math.sqrt(d.var_y_dark) / K + 0.5) / eta
    with np.errstate(divide="ignore", invalid="ignore"):
        snr = np.where(d.var_y > 0, sig / np.sqrt(np.maximum(d.var_y, 1e-300)), np.nan)
    L = d.n_stack
    s2_dark = max(np.var(d.dark_stack_mean) - d.var_y_dark / L, 0.0)
    s2_50 = max(np.var(d.bright_stack_mean) - d.var_y_bright / L, 0.0)
    mu50 = d.bright_stack_mean.mean() - d.mu_y_dark
    prnu = math.sqrt(max(s2_50 - s2_dark, 0.0)) / mu50
    g2, rn2 = two_frame_gain(d.mu_y[fit] - d.bias_dn, d.var_y[fit])
    return EmvaResult(
        system_gain_dn_per_e=K, system_gain_stderr=K_se, g_e_per_dn=1.0 / K, quantum_efficiency=eta,
        temporal_dark_noise_e=sigma_d, saturation_capacity_e=eta * mu_p_sat, saturation_photons=mu_p_sat,
        sensitivity_threshold_photons=mu_p_min, dynamic_range_db=20 * math.log10(mu_p_sat / mu_p_min),
        dynamic_range_stops=math.log2(mu_p_sat / mu_p_min), snr_max_db=20 * math.log10(float(snr[i_sat])),
        dsnu_e=math.sqrt(s2_dark) / K, prnu_percent=100.0 * prnu, two_frame_g_e_per_dn=g2, two_frame_read_noise_dn=rn2,
        linearity_error_percent=float(lin_err),
        # EMVA: below 0.24 DN^2 of dark variance the camera is quantisation limited and sigma_d an upper bound
        dark_noise_quantization_limited=bool(d.var_y_dark < 0.24),
        snr_curve={"mu_p": d.mu_p, "snr": snr, "mu_y": d.mu_y, "var_y": d.var_y,
                   "snr_ideal": np.sqrt(d.mu_p),
                   "snr_model": eta * d.mu_p / np.sqrt(sigma_d ** 2 + (1 / 12) / K ** 2 + eta * d.mu_p)},
        meta={"wavelength_nm": d.wavelength_nm, "exposure_s": d.exposure_s, "iso": d.iso, "channel": "RGB"[d.channel],
              "levels": int(d.mu_p.size), "levels_in_fit": int(fit.sum()), "pixels": d.n_pixels, "stack": d.n_stack,
              "responsivity_dn_per_photon": R, "responsivity_offset_dn": r0, "mu_y_dark": d.mu_y_dark,
              "var_y_dark": d.var_y_dark, "seconds": d.seconds})


def expected_emva(sensor: Sensor, *, iso: float | None = None, wavelength_nm: float = 540.0,
                  exposure_s: float = 0.01, channel: int = 1) -> dict[str, float]:
    """What the analysis should find for ``sensor`` (the truth the simulation was built from)."""
    iso = sensor.base_iso if iso is None else iso
    g = sensor.g_e_per_dn(iso)
    dark_e = sensor.dark_current_e_per_s * exposure_s
    dc_spatial = dark_e * sensor.dark_current_nonuniformity
    clip_e = min(sensor.full_well_e, (sensor.adc_max_dn - sensor.bias_dn) * g)
    return {"system_gain_dn_per_e": 1.0 / g, "g_e_per_dn": g,
            "quantum_efficiency": float(sensor.qe(np.array([wavelength_nm]))[0, channel]),
            "temporal_dark_noise_e": math.sqrt(sensor.read_noise_e(iso) ** 2 + dark_e),
            "read_noise_e": sensor.read_noise_e(iso), "saturation_capacity_e": clip_e,
            "dsnu_e": math.hypot(sensor.dsnu_e, dc_spatial), "prnu_percent": 100.0 * sensor.prnu}


def characterize(sensor: Sensor, *, rng: np.random.Generator, **kwargs: Any) -> tuple[EmvaResult, dict[str, float]]:
    """Simulate and analyse; returns the result and the expected values."""
    data = simulate_emva(sensor, rng=rng, **kwargs)
    keys = {k: kwargs[k] for k in ("iso", "wavelength_nm", "exposure_s", "channel") if k in kwargs}
    return analyse_emva(data), expected_emva(sensor, **keys)
