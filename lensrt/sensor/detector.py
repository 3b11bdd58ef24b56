"""Irradiance -> electrons -> DN: exposing a sensor, dark frames, frame averaging.

This is the interface the render stage calls::

    from lensrt.sensor import expose, get_preset
    raw = expose(get_preset("fullframe_24mp"), E, wavelength_nm, exposure_s=1/125, iso=400,
                 rng=np.random.default_rng(seed))

``E`` is the sensor-plane spectral irradiance, float array (rows, cols, n_wavelengths) in
W / (m^2 nm), averaged over each photosite, image origin top-left; ``wavelength_nm`` (n,)
is beside it, wavelength axis last. The result is a :class:`RawFrame`.

The chain per photosite (Field Guide pages):

1. mean photoelectrons n = t A_p sum (lambda / hc) QE_i E_lambda d lambda  (p. 40), times the
   PRNU gain map (p. 47);
2. Poisson photon shot noise (p. 46);
3. dark current, its mean set by a per-photosite rate map times t, with its own shot noise
   (p. 47);
4. clipping at the full-well capacity;
5. DSNU offset and upstream read noise (e-), the ISO gain, downstream read noise (DN), digital
   gain above the ISO-less setting (p. 50);
6. quantisation n_DN = INT(n_e / g) + bias, clipped to the M-bit range (p. 43, 49).

Each stage can be switched off with :class:`Switches` (e.g. for tests against formulas).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Sequence

import numpy as np

from ..errors import LensrtError
from .cfa import CFA
from .model import Sensor

__all__ = ["RawFrame", "Switches", "expose", "mean_photoelectrons", "electrons_to_raw", "dark_frame",
           "average_frames", "subtract_dark", "fixed_pattern_maps"]


@dataclass
class RawFrame:
    """A raw (mosaiced) frame and what is needed to develop it.

    Attributes
    ----------
    dn : numpy.ndarray
        Raw values, shape (rows, cols), origin top-left: uint16 for a single quantised frame,
        float32 for averaged, dark-subtracted or unquantised frames (DN).
    cfa : CFA
        The colour filter array (channel of each photosite).
    black_level_dn : float
        Raw value of zero signal (the bias, DN).
    white_level_dn : float
        Raw clipping point (DN).
    exposure_s, iso : float
        Integration time (s) and ISO setting.
    g_e_per_dn : float
        Conversion factor g (e-/DN) the frame was taken with.
    n_frames : int
        Number of frames averaged into ``dn``.
    meta : dict
        Free-form metadata (sensor name, seed, ...); values JSON-serialisable.
    """

    dn: np.ndarray
    cfa: CFA
    black_level_dn: float
    white_level_dn: float
    exposure_s: float
    iso: float
    g_e_per_dn: float
    n_frames: int = 1
    meta: dict = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        return self.dn.shape

    def normalized(self) -> np.ndarray:
        """(dn - black) / (white - black) as float32: 0 = black, 1 = raw clipping."""
        scale = 1.0 / (self.white_level_dn - self.black_level_dn)
        return ((self.dn.astype(np.float32) - np.float32(self.black_level_dn)) * np.float32(scale))

    def channel_values(self, channel: int) -> np.ndarray:
        """All raw values of one CFA channel (0 R, 1 G, 2 B), flattened (DN)."""
        return self.dn[self.cfa.channel_map(*self.dn.shape) == channel]


@dataclass(frozen=True)
class Switches:
    """Which stages of the sensor chain run (all on by default)."""

    shot_noise: bool = True
    dark_current: bool = True
    read_noise: bool = True
    fixed_pattern: bool = True
    full_well: bool = True
    quantize: bool = True

    @classmethod
    def noiseless(cls, quantize: bool = False) -> "Switches":
        """No random or fixed-pattern noise, no dark current: the mean response (for metrics)."""
        return cls(shot_noise=False, dark_current=False, read_noise=False, fixed_pattern=False, quantize=quantize)


def mean_photoelectrons(sensor: Sensor, irradiance_w_m2_nm: np.ndarray, wavelength_nm: np.ndarray,
                        exposure_s: float, *, bin_width_nm: np.ndarray | float | None = None,
                        labels: np.ndarray | None = None, shape: tuple[int, int] | None = None,
                        cfa: CFA | None = None) -> np.ndarray:
    """Mean photoelectrons of every photosite, noise-free and before PRNU (e-), float32 (rows, cols).

    Parameters
    ----------
    irradiance_w_m2_nm : array
        Sensor-plane spectral irradiance in W / (m^2 nm): (rows, cols, n) per photosite; or,
        with ``labels``, a table (k, n) of spectra indexed by ``labels``; or one spectrum (n,)
        for a uniform field of ``shape``.
    wavelength_nm : array (n,)
        Wavelengths of the last axis (nm), increasing.
    exposure_s : float
        Integration time t (s).
    bin_width_nm : array or float, optional
        Widths of spectral bins (nm) when the samples are bin averages (trapezoid rule otherwise).
    labels : int array (rows, cols), optional
        Index into the spectra table for each photosite (piecewise-uniform scenes, charts).
    shape : (rows, cols), optional
        Frame size for a uniform field.
    cfa : CFA, optional
        Defaults to the sensor's.
    """
    if not (exposure_s >= 0 and math.isfinite(exposure_s)):
        raise LensrtError(f"exposure time {exposure_s!r} s must be a finite number >= 0")
    wl = np.asarray(wavelength_nm, dtype=np.float64).ravel()
    E = np.asarray(irradiance_w_m2_nm)
    if E.shape[-1:] != wl.shape:
        raise LensrtError(f"irradiance has {E.shape[-1] if E.ndim else 0} wavelengths on its last axis but "
                          f"wavelength_nm has {wl.size}", hint="irradiance is (rows, cols, n) with the wavelength axis last")
    cfa = cfa or sensor.cfa
    W = sensor.electron_weights(wl, bin_width_nm) * exposure_s  # (n, 3): e- per (W m^-2 nm^-1)
    if labels is not None or E.ndim == 1:
        table = np.atleast_2d(E).astype(np.float64) @ W  # (k, 3)
        _check_values(table)
        if labels is None:
            if shape is None:
                raise LensrtError("a uniform spectrum needs the frame shape")
            labels = np.zeros(shape, dtype=np.intp)
        labels = np.asarray(labels)
        if labels.min() < 0 or labels.max() >= table.shape[0]:
            raise LensrtError("labels index outside the spectra table")
        cmap = cfa.channel_map(*labels.shape)
        return table[labels, cmap].astype(np.float32)
    if E.ndim != 3:
        raise LensrtError(f"irradiance must be (rows, cols, n_wavelengths); got shape {E.shape}")
    rows, cols, n = E.shape
    cmap = cfa.channel_map(rows, cols)
    out = np.empty((rows, cols), dtype=np.float32)
    Wt = W.astype(E.dtype if E.dtype in (np.float32, np.float64) else np.float64)
    step = max(1, (1 << 21) // max(1, cols * n))  # ~2M irradiance samples per block
    for r0 in range(0, rows, step):
        blk = E[r0:r0 + step]
        per = (blk.reshape(-1, n) @ Wt).reshape(blk.shape[0], cols, 3)
        _check_values(per)
        out[r0:r0 + step] = np.take_along_axis(per, cmap[r0:r0 + step, :, None].astype(np.intp), axis=2)[..., 0]
    return out


def _check_values(values: np.ndarray) -> None:
    if not np.all(np.isfinite(values)):
        raise LensrtError("irradiance holds NaN or infinite values")
    if values.size and values.min() < 0:
        raise LensrtError("irradiance must be >= 0 W/(m^2 nm)")


@lru_cache(maxsize=2)
def _fpn(seed: int, rows: int, cols: int, prnu: float, dsnu_e: float, dcnu: float) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng([int(seed), rows, cols, 1288])
    gain = (1.0 + prnu * rng.standard_normal((rows, cols), dtype=np.float32)).astype(np.float32)
    offset = (dsnu_e * rng.standard_normal((rows, cols), dtype=np.float32)).astype(np.float32)
    # dark current per photosite: log-normal with mean 1 and relative std dcnu (always >= 0)
    s = math.sqrt(math.log1p(dcnu * dcnu))
    dark = np.exp(s * rng.standard_normal((rows, cols), dtype=np.float32) - np.float32(0.5 * s * s)).astype(np.float32)
    for a in (gain, offset, dark):
        a.setflags(write=False)
    return gain, offset, dark


def fixed_pattern_maps(sensor: Sensor, rows: int, cols: int) -> dict[str, np.ndarray]:
    """The sensor's fixed-pattern maps for a ``rows`` x ``cols`` frame, deterministic per ``sensor.seed``.

    Returns ``prnu_gain`` (fraction, mean 1, p. 47), ``dsnu_offset_e`` (e-) and
    ``dark_current_scale`` (relative dark-current rate, mean 1).
    """
    g, o, d = _fpn(sensor.seed, rows, cols, float(sensor.prnu), float(sensor.dsnu_e), float(sensor.dark_current_nonuniformity))
    return {"prnu_gain": g, "dsnu_offset_e": o, "dark_current_scale": d}


def electrons_to_raw(sensor: Sensor, mean_electrons_e: np.ndarray, exposure_s: float, *, rng: np.random.Generator,
                     iso: float | None = None, switches: Switches = Switches(), cfa: CFA | None = None,
                     meta: dict | None = None) -> RawFrame:
    """Noise, clipping, gain and quantisation from mean photoelectrons to a raw frame.

    Parameters
    ----------
    mean_electrons_e : float array (rows, cols)
        Mean photoelectrons per photosite (e-), e.g. from :func:`mean_photoelectrons`.
    exposure_s : float
        Integration time (s), for the dark current.
    rng : numpy.random.Generator
        Source of the temporal noise (shot, dark shot, read); fixed-pattern noise comes from
        the sensor's seed instead.
    iso : float, optional
        ISO setting (default: base ISO).
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError("rng must be a numpy.random.Generator (lensrt never uses global random state)")
    if not (math.isfinite(exposure_s) and exposure_s >= 0):
        raise LensrtError(f"exposure time {exposure_s!r} s must be a finite number >= 0")
    iso = sensor.base_iso if iso is None else sensor.check_iso(float(iso))
    mean_e = np.asarray(mean_electrons_e, dtype=np.float32)
    rows, cols = mean_e.shape
    fpn = fixed_pattern_maps(sensor, rows, cols) if switches.fixed_pattern else None
    signal = mean_e * fpn["prnu_gain"] if fpn is not None else mean_e
    # photon shot noise is Poisson (p. 46); a mean far past any full well (an absurd exposure or irradiance)
    # is held at 1e15 e-, which numpy's Poisson sampler takes and the full-well clip makes irrelevant
    signal = np.minimum(np.nan_to_num(signal, nan=0.0, posinf=1e15), np.float32(1e15))
    electrons = rng.poisson(signal).astype(np.float32) if switches.shot_noise else signal.astype(np.float32, copy=True)
    if switches.dark_current and sensor.dark_current_e_per_s > 0 and exposure_s > 0:
        dark_mean = np.float32(min(sensor.dark_current_e_per_s * exposure_s, 1e15))
        dark = dark_mean * fpn["dark_current_scale"] if fpn is not None else np.full_like(electrons, dark_mean)
        electrons += rng.poisson(dark).astype(np.float32) if switches.shot_noise else dark
    if switches.full_well:
        np.minimum(electrons, np.float32(sensor.full_well_e), out=electrons)
    # upstream of the ISO amplifier: DSNU offset and read noise, both in e- (p. 47, p. 50)
    if fpn is not None and sensor.dsnu_e > 0:
        electrons += fpn["dsnu_offset_e"]
    if switches.read_noise and sensor.read_noise_upstream_e > 0:
        electrons += np.float32(sensor.read_noise_upstream_e) * rng.standard_normal((rows, cols), dtype=np.float32)
    # ISO gain (analog up to the ISO-less setting), then downstream read noise fixed in DN
    g_analog = sensor.g_base_e_per_dn / sensor.analog_gain(iso)
    value = electrons * np.float32(1.0 / g_analog)
    if switches.read_noise and sensor.read_noise_downstream_e > 0:
        sigma_down_dn = sensor.read_noise_downstream_e / sensor.g_base_e_per_dn
        value += np.float32(sigma_down_dn) * rng.standard_normal((rows, cols), dtype=np.float32)
    digital = sensor.digital_gain(iso)
    if digital != 1.0:
        value *= np.float32(digital)
    # ADC: n_DN = INT(n_e / g) + bias, clipped to 0 .. 2^M - 1 (p. 43, 49)
    value += np.float32(sensor.bias_dn)
    if switches.quantize:
        np.floor(value, out=value)
        np.clip(value, 0, sensor.adc_max_dn, out=value)
        dn = value.astype(np.uint16)
    else:
        dn = np.clip(value, 0, sensor.adc_max_dn, out=value)
    info = {"sensor": sensor.name, "sensor_seed": sensor.seed, "switches": {k: getattr(switches, k) for k in
            ("shot_noise", "dark_current", "read_noise", "fixed_pattern", "full_well", "quantize")}}
    return RawFrame(dn=dn, cfa=cfa or sensor.cfa, black_level_dn=float(sensor.bias_dn),
                    white_level_dn=sensor.white_level_dn(iso), exposure_s=float(exposure_s), iso=float(iso),
                    g_e_per_dn=sensor.g_e_per_dn(iso), meta={**info, **(meta or {})})


def expose(sensor: Sensor, irradiance_w_m2_nm: np.ndarray, wavelength_nm: np.ndarray, exposure_s: float, *,
           rng: np.random.Generator, iso: float | None = None, bin_width_nm: np.ndarray | float | None = None,
           labels: np.ndarray | None = None, shape: tuple[int, int] | None = None,
           switches: Switches = Switches(), meta: dict | None = None) -> RawFrame:
    """Expose ``sensor`` to a spectral irradiance for ``exposure_s`` seconds: the render stage's entry point.

    Parameters
    ----------
    sensor : Sensor
    irradiance_w_m2_nm : float array (rows, cols, n)
        Sensor-plane spectral irradiance, W / (m^2 nm), averaged over each photosite, origin
        top-left, wavelength axis last (or a (k, n) table with ``labels``, or one spectrum (n,)
        with ``shape``; see :func:`mean_photoelectrons`).
    wavelength_nm : float array (n,)
    exposure_s : float
        Integration time (s).
    rng : numpy.random.Generator
    iso : float, optional
        ISO setting (default: the sensor's base ISO).
    bin_width_nm : optional
        Spectral bin widths (nm) when the irradiance samples are bin averages.
    switches : Switches
        Stages to run.

    Returns
    -------
    RawFrame
    """
    mean_e = mean_photoelectrons(sensor, irradiance_w_m2_nm, wavelength_nm, exposure_s,
                                 bin_width_nm=bin_width_nm, labels=labels, shape=shape)
    return electrons_to_raw(sensor, mean_e, exposure_s, rng=rng, iso=iso, switches=switches, meta=meta)


def dark_frame(sensor: Sensor, shape: tuple[int, int], exposure_s: float, *, rng: np.random.Generator,
               iso: float | None = None, n_frames: int = 1, switches: Switches = Switches()) -> RawFrame:
    """A dark frame (shutter closed) of ``exposure_s``; with ``n_frames`` > 1 their average (p. 47)."""
    zeros = np.zeros(shape, dtype=np.float32)
    frames = [electrons_to_raw(sensor, zeros, exposure_s, rng=rng, iso=iso, switches=switches, meta={"dark": True})
              for _ in range(max(1, int(n_frames)))]
    return frames[0] if len(frames) == 1 else average_frames(frames)


def average_frames(frames: Sequence[RawFrame]) -> RawFrame:
    """Mean of N frames (float32 DN): temporal noise falls as 1/sqrt(N) (frame averaging, p. 46)."""
    if not frames:
        raise LensrtError("no frames to average")
    first = frames[0]
    if any(f.dn.shape != first.dn.shape or f.cfa != first.cfa for f in frames):
        raise LensrtError("frames to average must have the same size and CFA")
    acc = np.zeros(first.dn.shape, dtype=np.float64)
    n = 0
    for f in frames:
        acc += f.dn * f.n_frames
        n += f.n_frames
    return replace(first, dn=(acc / n).astype(np.float32), n_frames=n, meta={**first.meta, "averaged": n})


def subtract_dark(raw: RawFrame, dark: RawFrame) -> RawFrame:
    """Dark-frame subtraction (p. 47): removes the bias, dark-current mean and DSNU pattern.

    The result (float32) has black level 0; its white level is the raw's minus the dark
    frame's median. The dark frame's own temporal noise is added, so average many dark frames
    (``dark_frame(..., n_frames=16)``).
    """
    if dark.dn.shape != raw.dn.shape:
        raise LensrtError(f"dark frame {dark.dn.shape} and raw frame {raw.dn.shape} differ in size")
    d = dark.dn.astype(np.float32)
    out = raw.dn.astype(np.float32) - d
    return replace(raw, dn=out, black_level_dn=0.0, white_level_dn=float(raw.white_level_dn - np.median(d)),
                   meta={**raw.meta, "dark_subtracted": dark.n_frames})
