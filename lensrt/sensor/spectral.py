"""Spectral responses of the colour channels, and wavelength integration weights.

The quantum efficiency of channel i is (Field Guide p. 40)

    QE_i(lambda) = FF * eta(lambda) * T(lambda) * T_CFA,i(lambda)

with FF the fill factor, eta the silicon's internal QE, T the transmission of the cover
glass / IR-cut filter stack and T_CFA,i the colour filter. Published camera data
(colour-science's ``MSDS_CAMERA_SENSITIVITIES``, e.g. the NPL measurement of the Nikon D5100
that the Field Guide plots on p. 40) give eta * T * T_CFA,i for a whole camera as *relative*
curves, each scaled to a peak of 1. A :class:`SpectralResponse` holds such relative curves;
the sensor model scales each channel by its peak QE and multiplies by FF and, optionally, an
extra IR-cut filter.
"""
from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import LensrtError

__all__ = ["SpectralResponse", "camera_response", "load_response", "ir_cut_transmission",
           "integration_weights_nm", "CAMERA_DATASETS"]

#: short names for the camera sensitivity sets that colour-science ships
CAMERA_DATASETS = {"nikon_d5100": "Nikon 5100 (NPL)", "sigma_sd_merrill": "Sigma SDMerill (NPL)"}


@dataclass(frozen=True, eq=False)
class SpectralResponse:
    """Relative spectral response of the R, G, B channels.

    Attributes
    ----------
    wavelength_nm : numpy.ndarray
        Increasing sample wavelengths (nm), shape (n,).
    relative : numpy.ndarray
        Response of each channel at each wavelength, shape (n, 3), in R, G, B order. Relative
        curves (peak 1 per channel) are scaled by the sensor's peak QE; with ``absolute=True``
        the values are QE already (eta * T * T_CFA, without fill factor).
    source : str
        Where the data come from.
    absolute : bool
        Whether ``relative`` is an absolute QE (then the sensor's peak QE is not applied).

    Compared by identity (it holds arrays), so two sensors are equal only if they share it.
    """

    wavelength_nm: np.ndarray
    relative: np.ndarray
    source: str = ""
    absolute: bool = False

    def __post_init__(self) -> None:
        wl = np.asarray(self.wavelength_nm, dtype=np.float64)
        rel = np.asarray(self.relative, dtype=np.float64)
        if wl.ndim != 1 or rel.shape != (wl.size, 3):
            raise LensrtError(f"spectral response needs n wavelengths and an (n, 3) table; got {wl.shape} "
                              f"and {rel.shape}", path=self.source or None)
        if wl.size < 2 or np.any(np.diff(wl) <= 0):
            raise LensrtError("spectral response wavelengths must increase", path=self.source or None)
        if not np.all(np.isfinite(rel)) or np.any(rel < 0):
            raise LensrtError("spectral response values must be finite and >= 0", path=self.source or None)
        if self.absolute and rel.max() > 1.0:
            raise LensrtError("an absolute quantum efficiency cannot exceed 1", path=self.source or None)
        object.__setattr__(self, "wavelength_nm", wl)
        object.__setattr__(self, "relative", rel)

    def at(self, wavelength_nm: np.ndarray) -> np.ndarray:
        """Response interpolated linearly at ``wavelength_nm`` (nm), zero outside the data; (n, 3)."""
        w = np.asarray(wavelength_nm, dtype=np.float64)
        return np.stack([np.interp(w, self.wavelength_nm, self.relative[:, c], left=0.0, right=0.0)
                         for c in range(3)], axis=-1)


def camera_response(name: str = "nikon_d5100") -> SpectralResponse:
    """Camera spectral sensitivities shipped by colour-science, peak-normalised per channel.

    Parameters
    ----------
    name : str
        A key of :data:`CAMERA_DATASETS` (``nikon_d5100``, ``sigma_sd_merrill``) or
        colour-science's own name (``"Nikon 5100 (NPL)"``).
    """
    from ..colour.datacache import cached_tables
    full = CAMERA_DATASETS.get(name, name)
    t = cached_tables("camera_sensitivities", _camera_tables)
    names = [str(n) for n in t["names"]]
    hits = [i for i, n in enumerate(names) if n == full] or [i for i, n in enumerate(names)
                                                             if n.lower() == str(full).lower()]
    if not hits:
        raise LensrtError(f"unknown camera sensitivity set {name!r}",
                          hint=f"use one of {sorted(CAMERA_DATASETS)} or a CSV/JSON file")
    i = hits[0]
    values = np.clip(t[f"values{i}"], 0.0, None) / t[f"values{i}"].max(axis=0)
    return SpectralResponse(t[f"nm{i}"].copy(), values,
                            source=f"colour-science MSDS_CAMERA_SENSITIVITIES[{full!r}]")


def _camera_tables() -> dict[str, np.ndarray]:
    """colour-science's camera sensitivities: ``names``; per set i ``nm<i>`` and the (n, 3) ``values<i>``
    (kept on disk per colour-science version by :func:`lensrt.colour.datacache.cached_tables`)."""
    import colour
    out = {"names": np.array(list(colour.MSDS_CAMERA_SENSITIVITIES))}
    for i, msds in enumerate(colour.MSDS_CAMERA_SENSITIVITIES.values()):
        out[f"nm{i}"] = np.asarray(msds.wavelengths, dtype=np.float64)
        out[f"values{i}"] = np.asarray(msds.values, dtype=np.float64)
    return out


def load_response(path: str | Path, absolute: bool = False) -> SpectralResponse:
    """Read channel responses from a CSV or JSON file.

    CSV: a header row with ``wavelength_nm, r, g, b`` (case-insensitive; ``red``/``green``/
    ``blue`` also accepted), then one row per wavelength. JSON: an object
    ``{"wavelength_nm": [...], "r": [...], "g": [...], "b": [...], "absolute": false}``.
    With ``absolute`` true (argument or JSON key) the values are quantum efficiencies
    (0..1, without fill factor); otherwise relative curves scaled by the sensor's peak QE.
    """
    path = Path(path)
    if not path.is_file():
        raise LensrtError(f"no such spectral response file {path}")
    names = {"wavelength_nm": ("wavelength_nm", "wavelength", "lambda_nm", "nm"),
             "r": ("r", "red"), "g": ("g", "green"), "b": ("b", "blue")}
    if path.suffix.lower() == ".json":
        try:
            data = json.loads(path.read_text())
        except json.JSONDecodeError as err:
            raise LensrtError(f"not valid JSON: {err.msg}", path=path, line=err.lineno) from None
        if not isinstance(data, dict):
            raise LensrtError("expected a JSON object with wavelength_nm, r, g, b", path=path)
        lower = {str(k).lower(): v for k, v in data.items()}
        cols = {}
        for key, options in names.items():
            found = next((lower[o] for o in options if o in lower), None)
            if found is None:
                raise LensrtError(f"missing key {key!r}", path=path, hint="keys: wavelength_nm, r, g, b")
            cols[key] = found
        absolute = bool(lower.get("absolute", absolute))
        try:
            wl = np.asarray(cols["wavelength_nm"], dtype=np.float64)
            rel = np.stack([np.asarray(cols[k], dtype=np.float64) for k in "rgb"], axis=-1)
        except (ValueError, TypeError) as err:
            raise LensrtError(f"values must be numbers: {err}", path=path) from None
        return SpectralResponse(wl, rel, source=str(path), absolute=absolute)
    with path.open(newline="") as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].lstrip().startswith("#")]
    if len(rows) < 3:
        raise LensrtError("expected a header row and at least two data rows", path=path)
    header = [h.strip().lower() for h in rows[0]]
    idx = {}
    for key, options in names.items():
        found = next((header.index(o) for o in options if o in header), None)
        if found is None:
            raise LensrtError(f"missing column {key!r} in the header", path=path, line=1,
                              hint="header: wavelength_nm,r,g,b")
        idx[key] = found
    data = []
    for i, row in enumerate(rows[1:], start=2):
        try:
            data.append([float(row[idx[k]]) for k in ("wavelength_nm", "r", "g", "b")])
        except (ValueError, IndexError):
            raise LensrtError(f"cannot read row {row!r} as numbers", path=path, line=i) from None
    arr = np.asarray(data)
    return SpectralResponse(arr[:, 0], arr[:, 1:], source=str(path), absolute=absolute)


def ir_cut_transmission(wavelength_nm: np.ndarray, cut_nm: float, width_nm: float = 10.0) -> np.ndarray:
    """Transmission of a hot-mirror IR-cut filter: a logistic edge, 0.5 at ``cut_nm``.

    Parameters
    ----------
    wavelength_nm : array
        Wavelengths (nm).
    cut_nm : float
        50 % transmission wavelength (nm); typical camera filters sit near 650-680 nm.
    width_nm : float
        10-90 % edge width is about 4.4 * ``width_nm`` (nm).
    """
    w = np.asarray(wavelength_nm, dtype=np.float64)
    return 1.0 / (1.0 + np.exp((w - cut_nm) / width_nm))


def integration_weights_nm(wavelength_nm: np.ndarray, bin_width_nm: np.ndarray | float | None = None) -> np.ndarray:
    """Weights d(lambda) (nm) that turn samples of a spectral density into an integral.

    With ``bin_width_nm`` the samples are bin averages (e.g. a Monte Carlo render's spectral
    bins) and the weights are the bin widths; without it they are point samples of a smooth
    spectrum and the weights are the trapezoid rule's. A single wavelength without a bin width
    gets weight 1 nm (the irradiance is then taken as W/m^2 in a 1 nm band).
    """
    w = np.asarray(wavelength_nm, dtype=np.float64).ravel()
    if bin_width_nm is not None:
        bw = np.broadcast_to(np.asarray(bin_width_nm, dtype=np.float64), w.shape).copy()
        if np.any(bw <= 0):
            raise LensrtError("spectral bin widths must be > 0 nm")
        return bw
    if w.size == 1:
        return np.ones(1)
    if np.any(np.diff(w) <= 0):
        raise LensrtError("wavelength_nm must increase along the last axis of the irradiance")
    d = np.diff(w)
    out = np.zeros_like(w)
    out[:-1] += d / 2
    out[1:] += d / 2
    return out
