"""PSFs of a simulation: per depth layer, a grid of nodes over the frame, one PSF per wavelength band.

Each PSF comes from lensrt's stream kernel, the machinery of the PSF maps and the
bokeh tracer: Monte Carlo rays from a Lambertian object point at the layer's depth
over its *real* pupil box (iris and f-number included, so vignetting and cat's
eyes are in), placed so that its real chief ray (primary wavelength) lands on the
node (:func:`lensrt.analysis.bokeh.trace.object_heights_for_image`), one
wavelength per band, binned on the sensor at the image's own pixel pitch in a
window centred on the node's chief ray. So a PSF holds the blur *and* the band's
lateral colour (its offset from the primary chief ray); the warp moves the
image by the primary chief ray (:mod:`.optics`).

Interpolation error. For a few off-grid points (cell centres: the farthest from
the nodes), a PSF is traced directly, twice with independent seeds; the bilinear
blend of the four node PSFs is compared with it by the total-variation distance
(the fraction of the light put in the wrong place, 0.5 sum |a - b|), beside the
distance between the two direct PSFs (the Monte Carlo floor).

The grid is computed once per (lens, focus, aperture, frame, depths, bands, rays,
seed) and kept on disk (:func:`cache_dir`, keyed by a SHA-256 of those).
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import LensrtError
from .optics import Camera, picture_positions_mm
from .spectral import Bands

__all__ = ["PsfGrid", "compute_psf_grid", "hat_weights", "node_positions", "cache_dir", "blend_at",
           "total_variation", "FORMAT_VERSION"]

FORMAT_VERSION = 1
#: largest PSF window (pixels a side); wider blur is cut (its off-window fraction is reported)
MAX_PSF_PX = 257


@dataclass
class PsfGrid:
    """PSFs per layer: ``psf[l]`` (K bands, grid rows, grid cols, n, n) float32, unit sum, picture orientation
    (row down, col right; the centre pixel is the node's chief ray)."""

    node_rows: np.ndarray
    node_cols: np.ndarray
    depths_mm: np.ndarray
    psf: list
    rays_landed: np.ndarray  # (L, K, gr, gc)
    off_window: np.ndarray  # (L, K, gr, gc) fraction of the light outside the window
    checks: list = field(default_factory=list)
    seconds: float = 0.0
    rays: int = 0
    cached: bool = False
    key: str = ""

    def summary(self) -> dict:
        return {"grid": [len(self.node_rows), len(self.node_cols)], "depths_m": (self.depths_mm / 1000).tolist(),
                "psf_px": [int(p.shape[-1]) for p in self.psf], "rays_per_psf": int(self.rays),
                "rays_landed_min": int(self.rays_landed.min()), "off_window_max": float(self.off_window.max()),
                "seconds": self.seconds, "from_cache": self.cached, "cache_key": self.key,
                "interpolation_checks": self.checks}


def node_positions(n_pixels: int, n_nodes: int) -> np.ndarray:
    """``n_nodes`` pixel indices evenly over 0..n_pixels-1, ends included (at least 2)."""
    n = max(2, min(int(n_nodes), n_pixels))
    return np.unique(np.round(np.linspace(0, n_pixels - 1, n)).astype(int))


def hat_weights(nodes: np.ndarray, n_pixels: int) -> np.ndarray:
    """Bilinear (tent) weights (nodes, n_pixels): each pixel's two neighbouring nodes, summing to 1."""
    x = np.arange(n_pixels, dtype=np.float64)
    w = np.zeros((len(nodes), n_pixels))
    i = np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, len(nodes) - 2)
    t = (x - nodes[i]) / (nodes[i + 1] - nodes[i])
    w[i, np.arange(n_pixels)] = 1.0 - t
    w[i + 1, np.arange(n_pixels)] += t
    return w


def blend_at(psf_band: np.ndarray, wr: np.ndarray, wc: np.ndarray) -> np.ndarray:
    """The bilinear blend sum_ij wr_i wc_j psf[i, j] of node PSFs (gr, gc, n, n)."""
    return np.einsum("i,j,ijyx->yx", wr, wc, psf_band)


def total_variation(a: np.ndarray, b: np.ndarray) -> float:
    """0.5 sum |a - b| of two unit-sum PSFs: the fraction of light in the wrong place."""
    return 0.5 * float(np.abs(a - b).sum())


def cache_dir(override: str | Path | None = None) -> Path:
    """Where PSF grids are kept: ``override``, else $LENSRT_CACHE/simulate, else ~/.cache/lensrt/simulate."""
    if override is not None:
        return Path(override)
    base = os.environ.get("LENSRT_CACHE")
    return (Path(base) if base else Path.home() / ".cache" / "lensrt") / "simulate"


def _seed(*parts: int) -> int:
    return int(np.random.SeedSequence([int(p) for p in parts]).generate_state(1)[0]) & 0x7FFFFFFF


def _layer_sources(cam: Camera, depth_mm: float, pix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(object points (S, 3), sensor targets (S, 2)) of pixel positions ``pix`` (S, 2) = (row, col)."""
    from .optics import object_heights
    u, v = picture_positions_mm(cam, pix[:, 0], pix[:, 1])
    tx, ty = -u, -v
    rad = np.hypot(tx, ty)
    y = object_heights(cam, depth_mm, rad)
    with np.errstate(invalid="ignore", divide="ignore"):
        ux, uy = np.where(rad > 0, tx / np.where(rad > 0, rad, 1), 0.0), np.where(rad > 0, ty / np.where(rad > 0, rad, 1), 1.0)
    obj = np.stack([ux * y, uy * y, np.full_like(y, -depth_mm)], axis=1)
    return obj, np.stack([tx, ty], axis=1)


def _window_half(cam: Camera, foot: np.ndarray, targets: np.ndarray) -> int:
    """Half-size (pixels) of a window that holds every footprint about its target (+10 %, +2 px)."""
    ext = np.nanmax(np.abs(np.concatenate([foot[:, 0:2] - targets[:, :1], foot[:, 2:4] - targets[:, 1:]], axis=1)))
    if not math.isfinite(ext):
        raise LensrtError("a PSF node is fully vignetted: no ray reaches the sensor", hint="use a smaller --sensor")
    return int(min(math.ceil(1.1 * ext / cam.pitch_mm) + 2, (MAX_PSF_PX - 1) // 2))


def _check_pixels(rows: np.ndarray, cols: np.ndarray) -> list[tuple[int, int]]:
    """Cell centres to check the interpolation at: the top-left (corner) cell and the central cell."""
    pts = []
    for i, j in {(0, 0), ((len(rows) - 2) // 2, (len(cols) - 2) // 2)}:
        pts.append((int(round(0.5 * (rows[i] + rows[i + 1]))), int(round(0.5 * (cols[j] + cols[j + 1])))))
    return sorted(pts)


def _stream_layer(cam: Camera, bands: Bands, depth_mm: float, li: int, pix: np.ndarray, n_check: int,
                  check_band: int, rays: int, seed: int) -> dict:
    """One stream launch: every node x band, plus two direct PSFs per check point; histograms per source."""
    from ..analysis.bokeh.trace import pupil_boxes
    from ..trace.aiming import FieldPoint
    from ..trace.sampling import spectrum_discrete
    from ..trace.stream import Grid, StreamSource, stream
    obj, tgt = _layer_sources(cam, depth_mm, pix)
    wls = sorted({float(bands.centre_nm.min()), cam.wavelength_nm, float(bands.centre_nm.max())})
    boxes, foot = pupil_boxes(cam.lens, obj, wls, cam.sensor_z_mm, stop_radius_mm=cam.stop_radius_mm, device=cam.device,
                             coarse=64, fine=48)
    half = _window_half(cam, foot, tgt)
    n_nodes = len(pix) - n_check
    plan = [(k, b) for k in range(n_nodes) for b in range(bands.count)]
    plan += [(n_nodes + c, check_band) for c in range(n_check // 2 * 2)]
    srcs = []
    for layer, (k, b) in enumerate(plan):
        fp = FieldPoint(False, None, tuple(float(v) for v in obj[k]))
        srcs.append(StreamSource(fp, boxes[k], cam.sensor_z_mm, (float(tgt[k, 0]), float(tgt[k, 1])), layer,
                                 "lambertian", seed=_seed(seed, li, k, b), rng_index=0, spectrum=b))
    spectra = [spectrum_discrete([float(c)]) for c in bands.centre_nm]
    n = 2 * half + 1
    res = stream(cam.lens, srcs, Grid(n, n, cam.pitch_mm), rays, spectrum=spectra, seed=seed, batches=16,
                 device=cam.device, stop_radius_mm=cam.stop_radius_mm)
    hist = np.asarray(res.histogram[:, 0], dtype=np.float64)[:, :, ::-1]  # picture orientation (see module doc)
    tot = hist.sum(axis=(1, 2))
    w_all = np.array([res.batch_stats[j][:, 1].sum() for j in range(len(srcs))])
    landed = np.array([res.status_counts(j)["OK"] - res.status_counts(j)["OUTSIDE_GRID"] for j in range(len(srcs))])
    if np.any(tot <= 0):
        raise LensrtError(f"no ray from {depth_mm / 1000:g} m reaches a PSF window", hint="use a smaller --sensor")
    psf = (hist / tot[:, None, None]).astype(np.float32)
    off = np.where(w_all > 0, 1.0 - tot / np.maximum(w_all, 1e-300), 0.0)
    return {"psf": psf, "landed": landed, "off": np.clip(off, 0.0, 1.0), "plan": plan, "rays": res.rays_per_source,
            "n_nodes": n_nodes}


def _grid_key(cam: Camera, bands: Bands, depths_mm: Sequence[float], rows: np.ndarray, cols: np.ndarray,
              rays: int, seed: int) -> str:
    key = {"v": FORMAT_VERSION, "camera": cam.key(), "bands": bands.centre_nm.tolist(),
           "depths_mm": [float(d) for d in depths_mm], "rows": rows.tolist(), "cols": cols.tolist(),
           "rays": int(rays), "seed": int(seed), "max_psf_px": MAX_PSF_PX}
    return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:24]


def _load(path: Path, grid: PsfGrid) -> bool:
    try:
        with np.load(path, allow_pickle=False) as z:
            grid.psf = [z[f"psf{i}"] for i in range(len(grid.depths_mm))]
            grid.rays_landed, grid.off_window = z["landed"], z["off"]
            meta = json.loads(str(z["meta"]))
    except (OSError, KeyError, ValueError):
        return False
    grid.checks, grid.rays, grid.seconds, grid.cached = meta["checks"], meta["rays"], meta["seconds"], True
    return True


def _save(path: Path, grid: PsfGrid) -> None:
    meta = json.dumps({"checks": grid.checks, "rays": grid.rays, "seconds": grid.seconds})
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        # uncompressed: a warm run reads hundreds of MB of PSFs (12 MP) in a fraction of a second, not seconds
        np.savez(tmp, landed=grid.rays_landed, off=grid.off_window, meta=np.array(meta),
                 **{f"psf{i}": p for i, p in enumerate(grid.psf)})
        os.replace(tmp, path)
    except OSError as err:
        raise LensrtError(f"cannot write the PSF cache {path}: {err}", hint="give --cache-dir or --no-cache") from None


def _checks(out: dict, rows, cols, check_pix, bands: Bands, check_band: int, li: int, depth_mm: float) -> list[dict]:
    gr, gc = len(rows), len(cols)
    psf_b = out["psf"][:out["n_nodes"] * bands.count].reshape(gr, gc, bands.count, *out["psf"].shape[1:])
    wr_all, wc_all = hat_weights(rows, int(rows[-1]) + 1), hat_weights(cols, int(cols[-1]) + 1)
    base = out["n_nodes"] * bands.count
    res = []
    for c, (r, col) in enumerate(check_pix):
        a, b = out["psf"][base + 2 * c].astype(np.float64), out["psf"][base + 2 * c + 1].astype(np.float64)
        blend = blend_at(psf_b[:, :, check_band].astype(np.float64), wr_all[:, r], wc_all[:, col])
        res.append({"layer": li, "depth_m": depth_mm / 1000.0, "pixel": [r, col], "band_nm": float(bands.centre_nm[check_band]),
                    "tv_interpolated_vs_direct": total_variation(blend, a),
                    "tv_direct_vs_direct": total_variation(a, b)})
    return res


def compute_psf_grid(cam: Camera, bands: Bands, depths_mm: Sequence[float], grid: tuple[int, int] = (5, 7),
                     rays: int = 1 << 15, seed: int = 0, cache: str | Path | None = None, use_cache: bool = True,
                     check: bool = True) -> PsfGrid:
    """The PSF grid of every depth layer (module docstring); from the cache when it is there."""
    rows, cols = node_positions(cam.shape[0], grid[0]), node_positions(cam.shape[1], grid[1])
    depths = np.asarray([float(d) for d in depths_mm])
    key = _grid_key(cam, bands, depths, rows, cols, rays, seed)
    out = PsfGrid(rows, cols, depths, [], np.zeros(0), np.zeros(0), key=key)
    path = cache_dir(cache) / f"psf_{key}.npz"
    if use_cache and path.is_file() and _load(path, out):
        return out
    t0 = time.perf_counter()
    check_pix = _check_pixels(rows, cols) if check else []
    check_band = int(np.argmin(np.abs(bands.centre_nm - cam.wavelength_nm)))
    node_pix = np.array([(r, c) for r in rows for c in cols] + [p for p in check_pix for _ in range(2)], dtype=float)
    landed, off = [], []
    for li, d in enumerate(depths):
        o = _stream_layer(cam, bands, float(d), li, node_pix, 2 * len(check_pix), check_band, rays, seed)
        k = o["n_nodes"] * bands.count
        shape = (len(rows), len(cols), bands.count)
        out.psf.append(np.ascontiguousarray(o["psf"][:k].reshape(*shape, *o["psf"].shape[1:]).transpose(2, 0, 1, 3, 4)))
        landed.append(o["landed"][:k].reshape(shape).transpose(2, 0, 1))
        off.append(o["off"][:k].reshape(shape).transpose(2, 0, 1))
        out.checks += _checks(o, rows, cols, check_pix, bands, check_band, li, float(d))
        out.rays = int(o["rays"])
    out.rays_landed, out.off_window = np.array(landed), np.array(off)
    out.seconds = time.perf_counter() - t0
    if use_cache:
        _save(path, out)
    return out
