"""``lensrt sensor presets|show|characterize|expose``: the sensor model and raw conversion."""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from ._common import emit, print_json
from ._limits import add_max_memory_argument, parse_seed

__all__ = ["register"]


def _add_sensor_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--preset", default="fullframe_24mp", help="sensor preset (see `lensrt sensor presets`)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a sensor parameter, e.g. --set cfa=XTRANS --set read_noise_upstream_e=3 (repeatable)")
    p.add_argument("--iso", type=float, default=None, help="ISO setting (default: the sensor's base ISO)")
    p.add_argument("--seed", type=parse_seed, default=0, help="seed of the temporal noise (numpy Generator), 0..2^63-1")
    add_max_memory_argument(p)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sensor", help="sensor presets, EMVA 1288 characterisation, exposing and developing raw frames")
    ssub = p.add_subparsers(dest="sensor_command", metavar="ACTION")
    ssub.required = True

    pr = ssub.add_parser("presets", help="table of the preset sensors")
    pr.add_argument("--json", action="store_true")
    pr.set_defaults(func=cmd_presets)

    sh = ssub.add_parser("show", help="all parameters of a sensor with their sources, and per-ISO gain, noise, DR, SOS")
    _add_sensor_options(sh)
    sh.add_argument("--json", action="store_true")
    sh.set_defaults(func=cmd_show)

    ch = ssub.add_parser("characterize", help="simulate and analyse an EMVA 1288 photon-transfer measurement")
    _add_sensor_options(ch)
    ch.add_argument("--wavelength-nm", type=float, default=540.0, help="monochromatic light (nm), default 540")
    ch.add_argument("--exposure-s", type=float, default=0.01, help="exposure time (s), default 0.01")
    ch.add_argument("--levels", type=int, default=40, help="irradiance steps (default 40)")
    ch.add_argument("--size", default="256x256", help="frame size ROWSxCOLS (default 256x256)")
    ch.add_argument("--channel", choices=["R", "G", "B"], default="G")
    ch.add_argument("--stack", type=int, default=16, help="frames averaged for DSNU/PRNU (default 16)")
    ch.add_argument("--json", action="store_true")
    ch.add_argument("--plot", metavar="DIR", help="write photon_transfer.png and snr.png here")
    ch.set_defaults(func=cmd_characterize)

    ex = ssub.add_parser("expose", help="expose a spectral irradiance, flat field or ColorChecker; write raw and sRGB")
    _add_sensor_options(ex)
    src = ex.add_mutually_exclusive_group(required=True)
    src.add_argument("--irradiance", metavar="FILE", help="spectral irradiance: .exr (lensrt spectral EXR) or .npz "
                     "(arrays irradiance (rows, cols, n) in W/(m^2 nm) and wavelength_nm)")
    src.add_argument("--flat", type=float, metavar="LUX", help="uniform field of this sensor-plane illuminance (lux)")
    src.add_argument("--colorchecker", action="store_true", help="the 24-patch ColorChecker (colour-science spectra)")
    ex.add_argument("--illuminant", default="D65", help="illuminant of flat/chart and adopted white: D65, A, F2, planck:3200K, daylight:5000K ...")
    ex.add_argument("--exposure-s", type=float, help="exposure time (s); default: set by --level")
    ex.add_argument("--level", type=float, default=0.7,
                    help="without --exposure-s: the brightest green signal (chart: a perfect white) at this fraction of raw clipping")
    ex.add_argument("--size", default="400x600", help="flat-field size ROWSxCOLS (default 400x600)")
    ex.add_argument("--patch-px", type=int, default=32, help="ColorChecker patch size in photosites (default 32)")
    ex.add_argument("--frames", type=int, default=1, help="average this many frames (p. 46)")
    ex.add_argument("--dark-frames", type=int, default=0, help="subtract a master dark of this many frames (p. 47)")
    ex.add_argument("--demosaic", default="bilinear", help="bilinear, malvar2004, menon2007 (Bayer) or normalized")
    ex.add_argument("--wb", default="illuminant", help="illuminant, grey (a chart's neutral patch) or R,G,B multipliers")
    ex.add_argument("--matrix", choices=["lstsq", "de2000"], default="lstsq", help="colour matrix fit")
    ex.add_argument("--tone", default="srgb", help="srgb, linear or scurve[:CONTRAST]")
    ex.add_argument("--gain", default="auto", help="digital exposure gain: a number, sos (SOS = ISO), or auto "
                    "(chart: perfect white -> 1; otherwise sos)")
    ex.add_argument("--raw", metavar="OUT.exr|dng", help="write the raw mosaic: .exr (UINT channel + metadata) or "
                    ".dng (needs the optional pidng package)")
    ex.add_argument("--out", metavar="OUT.png", help="write 8-bit sRGB PNG")
    ex.add_argument("--out16", metavar="OUT.tif|png", help="write 16-bit sRGB TIFF or PNG")
    ex.add_argument("--linear", metavar="OUT.exr", help="write linear sRGB (float) EXR")
    ex.add_argument("--hist", metavar="OUT.png", help="write raw and output histograms")
    ex.add_argument("--json", action="store_true")
    ex.set_defaults(func=cmd_expose)


def _value(text: str):
    low = text.strip().lower()
    if low in ("none", "null"):
        return None
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    if "," in text:
        parts = [p.strip() for p in text.split(",")]
        try:
            return [float(p) for p in parts]
        except ValueError:
            return parts
    return text


def _sensor(args: argparse.Namespace):
    from ..errors import LensrtError
    from ..sensor import sensor_from_spec
    spec = {"preset": args.preset}
    for item in args.set:
        if "=" not in item:
            raise LensrtError(f"--set {item!r} must be KEY=VALUE")
        k, v = item.split("=", 1)
        spec[k.strip()] = _value(v)
    sensor = sensor_from_spec(spec)
    iso = sensor.base_iso if args.iso is None else sensor.check_iso(args.iso)
    return sensor, iso


def _size(text: str, args: argparse.Namespace | None = None) -> tuple[int, int]:
    """``--size ROWSxCOLS``, checked against the memory budget (``--max-memory``)."""
    from ..core.budget import check_memory, estimate_sensor_bytes
    from ..errors import LensrtError
    from ._limits import memory_limit
    try:
        r, c = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise LensrtError(f"--size {text!r} must be ROWSxCOLS, e.g. 256x256") from None
    if r < 4 or c < 4:
        raise LensrtError(f"--size {text}: frames need at least 4x4 photosites")
    check_memory(estimate_sensor_bytes(r, c, what=f"--size {text}: a frame"), None if args is None else memory_limit(args))
    return r, c


#: the longest exposure time the sensor commands take (s): a day
MAX_EXPOSURE_S = 86400.0


def _check_exposure(value: float | None) -> None:
    from ..errors import LensrtError
    if value is not None and not (math.isfinite(value) and 0 < value <= MAX_EXPOSURE_S):
        raise LensrtError(f"--exposure-s: exposure time {value:g} s is outside (0, {MAX_EXPOSURE_S:g}] s")


def _check_chart(args: argparse.Namespace) -> None:
    """``--colorchecker --patch-px``: a patch size the memory budget allows."""
    from ..core.budget import check_memory, estimate_sensor_bytes
    from ..errors import LensrtError
    from ._limits import memory_limit
    if args.patch_px > 4096:
        raise LensrtError(f"--patch-px {args.patch_px} is more than 4096 photosites a patch")
    check_memory(estimate_sensor_bytes(5 * args.patch_px, 7 * args.patch_px, what="--patch-px: a chart"),
                 memory_limit(args))


def _check_characterize(args: argparse.Namespace) -> None:
    from ..errors import LensrtError
    _check_exposure(args.exposure_s)
    if args.stack < 1:
        raise LensrtError(f"--stack {args.stack}: at least 1 frame must be averaged for DSNU/PRNU")
    if not 8 <= args.levels <= 10000:
        raise LensrtError(f"--levels {args.levels} must be 8..10000 irradiance steps")
    if not (math.isfinite(args.wavelength_nm) and 200.0 <= args.wavelength_nm <= 2000.0):
        raise LensrtError(f"--wavelength-nm {args.wavelength_nm:g} is outside 200..2000 nm")


def cmd_presets(args: argparse.Namespace) -> int:
    from ..io.table import format_table
    from ..sensor import PRESETS, get_preset
    rows = []
    for name in PRESETS:
        s = get_preset(name)
        rows.append([name, f"{s.cols}x{s.rows}", s.pixel_pitch_um, s.cfa.name, s.full_well_e, s.read_noise_e(s.base_iso),
                     s.read_noise_e(s.iso_less_iso), s.base_iso, s.iso_less_iso, s.adc_bits, s.g_base_e_per_dn,
                     s.raw_dynamic_range_stops(s.base_iso), s.description])
    headers = ["preset", "pixels", "pitch_um", "cfa", "full_well_e", "read_e@base", "read_e@isoless", "base_iso",
               "isoless_iso", "adc_bits", "g_base_e/DN", "raw_DR_stops", "description"]
    if args.json:
        print_json([dict(zip(headers, r)) for r in rows])
        return 0
    emit(format_table(rows, headers, digits=2))
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    from ..io.table import format_table
    from ..isp import Isp, image_dynamic_range_stops, sos_iso
    sensor, iso = _sensor(args)
    summary = sensor.summary()
    isp = Isp(sensor)
    summary["derived"]["sos_iso_at_gain_1"] = sos_iso(isp, iso)
    summary["derived"]["srgb_image_dynamic_range_stops"] = image_dynamic_range_stops("srgb", 8)
    if args.json:
        print_json(summary)
        return 0
    emit(f"{sensor.name}: {sensor.description}")
    params = [[k, v if not isinstance(v, (list, tuple)) else ", ".join(f"{x:g}" for x in v), sensor.sources.get(k, "")]
              for k, v in summary.items() if k not in ("derived", "sources", "name", "description")]
    emit(format_table(params, ["parameter", "value", "source"], digits=4))
    d = summary["derived"]
    emit("")
    emit(f"{d['megapixels']:.1f} MP, {d['sensor_width_mm']:.2f} x {d['sensor_height_mm']:.2f} mm; "
         f"g at base ISO {d['g_base_e_per_dn']:.4g} e-/DN; unity gain at ISO {d['unity_gain_iso']:.0f} (p. 43)")
    emit(format_table([[r["iso"], r["g_e_per_dn"], r["read_noise_e"], r["read_noise_dn"], r["white_level_dn"],
                        r["raw_dynamic_range_stops"]] for r in d["per_iso"]],
                      ["iso", "g_e/DN", "read_noise_e", "read_noise_DN", "white_DN", "raw_DR_stops"], digits=3,
                      title="per ISO (read noise p. 50, raw DR = log2(n_clip / sigma_read) p. 51):"))
    emit(f"SOS ISO of sensor + default ISP (gain 1, raw clip -> sRGB 255) at ISO {iso:g}: "
         f"{d['sos_iso_at_gain_1']:.1f} (p. 77)")
    emit(f"image dynamic range of the 8-bit sRGB curve: {d['srgb_image_dynamic_range_stops']:.2f} stops (p. 70)")
    return 0


def cmd_characterize(args: argparse.Namespace) -> int:
    import numpy as np
    from ..io.table import format_table
    from ..sensor.emva import characterize
    sensor, iso = _sensor(args)
    shape = _size(args.size, args)
    _check_characterize(args)
    result, expected = characterize(sensor, rng=np.random.default_rng(args.seed), iso=iso,
                                    wavelength_nm=args.wavelength_nm, exposure_s=args.exposure_s, n_levels=args.levels,
                                    shape=shape, channel="RGB".index(args.channel), n_stack=args.stack)
    files = []
    if args.plot:
        from ..views.plots.sensor import plot_emva
        files = [str(f) for f in plot_emva(result, args.plot)]
    if args.json:
        out = result.to_dict()
        out["expected"] = expected
        out["files"] = files
        print_json(out)
        return 0
    m = result.meta
    emit(f"EMVA 1288 characterisation of {sensor.name}, channel {m['channel']} at {m['wavelength_nm']:g} nm, "
         f"ISO {m['iso']:g}, t = {m['exposure_s']:g} s; {m['levels']} levels ({m['levels_in_fit']} in the fit), "
         f"{m['pixels']} photosites, stacks of {m['stack']}; {m['seconds']:.2f} s")
    rows = [["system gain K (DN/e-)", result.system_gain_dn_per_e, expected["system_gain_dn_per_e"]],
            ["  +- standard error", result.system_gain_stderr, None],
            ["g = 1/K (e-/DN)", result.g_e_per_dn, expected["g_e_per_dn"]],
            ["g, two-frame method p. 48 (e-/DN)", result.two_frame_g_e_per_dn, expected["g_e_per_dn"]],
            ["quantum efficiency", result.quantum_efficiency, expected["quantum_efficiency"]],
            ["temporal dark noise (e-)", result.temporal_dark_noise_e, expected["temporal_dark_noise_e"]],
            ["saturation capacity (e-)", result.saturation_capacity_e, expected["saturation_capacity_e"]],
            ["DSNU (e-)", result.dsnu_e, expected["dsnu_e"]],
            ["PRNU (%)", result.prnu_percent, expected["prnu_percent"]],
            ["dynamic range (dB)", result.dynamic_range_db, None],
            ["dynamic range (stops)", result.dynamic_range_stops, None],
            ["max SNR (dB)", result.snr_max_db, None],
            ["linearity error (%)", result.linearity_error_percent, None]]
    emit(format_table(rows, ["quantity", "measured", "model"], digits=4))
    if result.dark_noise_quantization_limited:
        emit("note: dark variance < 0.24 DN^2 -- quantisation limited; temporal dark noise is an upper bound (EMVA 1288)")
    emit("saturation: EMVA takes the level of maximum variance, a little below the clipping point the model lists")
    for f in files:
        emit(f"wrote {f}")
    return 0


def _tone(text: str):
    from ..errors import LensrtError
    from ..isp import SCurve
    if text.startswith("scurve"):
        if ":" not in text:
            return SCurve()
        try:
            return SCurve(float(text.split(":", 1)[1]))
        except ValueError:
            raise LensrtError(f"--tone {text!r}: the contrast after 'scurve:' must be a number",
                              hint="e.g. scurve:1.4") from None
    return text


def cmd_expose(args: argparse.Namespace) -> int:
    import numpy as np
    from ..errors import LensrtError
    from ..io.table import format_table
    from ..isp import Isp, IspSettings, exposure_gain_for_iso
    from ..sensor import average_frames, dark_frame, electrons_to_raw, mean_photoelectrons
    from ..colour import STANDARD_WAVELENGTHS_NM, parse_illuminant
    from ..sensor.exposure import spectral_irradiance_from_illuminance
    t_start = time.perf_counter()
    _check_exposure(args.exposure_s)
    size = _size(args.size, args) if args.flat is not None else None  # before any work
    sensor, iso = _sensor(args)
    rng = np.random.default_rng(args.seed)
    chart = None
    bin_width = None
    illuminant = parse_illuminant(args.illuminant)
    if args.colorchecker:
        from ..sensor.targets import colorchecker_scene
        _check_chart(args)
        chart = colorchecker_scene(args.patch_px, illuminant)
        E, wl, labels, shape = chart.spectra, chart.wavelength_nm, chart.labels, None
    elif args.flat is not None:
        wl = STANDARD_WAVELENGTHS_NM
        E, labels, shape = spectral_irradiance_from_illuminance(args.flat, illuminant, wl), None, size
    else:
        E, wl, bin_width = _read_irradiance(args.irradiance)
        labels, shape = None, None
    clip_e = min(sensor.full_well_e, (sensor.white_level_dn(iso) - sensor.bias_dn) * sensor.g_e_per_dn(iso))
    per_s = mean_photoelectrons(sensor, E, wl, 1.0, bin_width_nm=bin_width, labels=labels, shape=shape)
    if chart is not None:  # perfect white reflector's green electrons per second
        white = chart.spectra[18] / chart.reflectance[18]
        ref_e = float((white @ sensor.electron_weights(wl))[1])
    else:
        gmask = sensor.cfa.channel_map(*per_s.shape) == 1
        ref_e = float(np.percentile(per_s[gmask], 99.9))
    if args.exposure_s is not None:
        t = args.exposure_s
    else:
        if not (0 < args.level <= 4):
            raise LensrtError("--level must be in (0, 4]")
        if ref_e <= 0:
            raise LensrtError("the irradiance gives no signal; pass --exposure-s")
        t = args.level * clip_e / ref_e
    if args.frames < 1 or args.dark_frames < 0:
        raise LensrtError(f"--frames {args.frames} must be at least 1 and --dark-frames {args.dark_frames} at least 0")
    mean_e = per_s * np.float32(t)
    frames = [electrons_to_raw(sensor, mean_e, t, rng=rng, iso=iso) for _ in range(args.frames)]
    raw = frames[0] if len(frames) == 1 else average_frames(frames)
    dark = dark_frame(sensor, raw.dn.shape, t, rng=rng, iso=iso, n_frames=args.dark_frames) if args.dark_frames > 0 else None
    # white balance and exposure gain
    grey_region = None
    if args.wb == "illuminant":
        wb = "illuminant"
    elif args.wb == "grey":
        if chart is None:
            raise LensrtError("--wb grey needs --colorchecker (it uses the neutral patch 'neutral 5')")
        wb, grey_region = "grey", chart.boxes[21]
    else:
        vals = _value(args.wb)
        if not (isinstance(vals, list) and len(vals) == 3):
            raise LensrtError("--wb must be illuminant, grey or three multipliers R,G,B")
        wb = tuple(float(v) for v in vals)
    settings = IspSettings(illuminant=illuminant, white_balance=wb, grey_region=grey_region, demosaic=args.demosaic,
                           matrix_method=args.matrix, tone=_tone(args.tone))
    isp = Isp(sensor, settings)
    if args.gain == "auto":
        gain_kind = "white" if chart is not None else "sos"
    else:
        gain_kind = args.gain
    if gain_kind == "white":
        gain = clip_e / (ref_e * t)  # perfect white -> linear 1.0
    elif gain_kind == "sos":
        gain = exposure_gain_for_iso(isp, iso)
    else:
        try:
            gain = float(gain_kind)
        except ValueError:
            raise LensrtError(f"--gain {args.gain!r} must be a number, sos or auto") from None
    isp = isp.with_settings(exposure_gain=gain)
    result = isp.develop(raw, dark=dark)
    files = _write_outputs(args, sensor, raw, result)
    report = {"sensor": sensor.name, "cfa": sensor.cfa.name, "iso": iso, "exposure_s": t, "g_e_per_dn": raw.g_e_per_dn,
              "frames": raw.n_frames, "dark_frames": args.dark_frames, "exposure_gain": gain,
              "wb_multipliers": result.wb_multipliers, "camera_to_srgb": result.camera_to_srgb,
              "raw_mean_dn": float(raw.dn.mean()), "raw_max_dn": float(raw.dn.max()),
              "white_level_dn": raw.white_level_dn, "black_level_dn": raw.black_level_dn,
              "isp_seconds": result.seconds, "seconds": time.perf_counter() - t_start, "files": files}
    if chart is not None:
        from ..colour import srgb_matrix_for_white
        from ..isp.colour import delta_e2000_srgb, xyz_of_reflectances
        X, wxyz = xyz_of_reflectances(chart.reflectance, illuminant, wl)
        ref = X @ srgb_matrix_for_white(wxyz).T   # the colours the ISP aims at (adopted white -> sRGB white)
        got = np.array([result.linear[r0:r1, c0:c1].reshape(-1, 3).mean(axis=0) for r0, r1, c0, c1 in chart.boxes])
        de = delta_e2000_srgb(got, ref)
        report["delta_e2000"] = {"mean": float(de.mean()), "max": float(de.max()),
                                 "patches": dict(zip(chart.names, de.round(3).tolist()))}
    if args.json:
        print_json(report)
        return 0
    emit(f"{sensor.name} ({sensor.cfa.name}) at ISO {iso:g}, t = {t:.6g} s, g = {raw.g_e_per_dn:.4g} e-/DN, "
         f"{raw.n_frames} frame(s), dark frames {args.dark_frames}; exposure gain {gain:.4g}")
    emit(f"raw mean {report['raw_mean_dn']:.1f} DN, max {report['raw_max_dn']:.0f} DN (black {raw.black_level_dn:g}, "
         f"white {raw.white_level_dn:g}); WB multipliers R {result.wb_multipliers[0]:.4f} B {result.wb_multipliers[2]:.4f}")
    if chart is not None:
        rows = [[n, v] for n, v in report["delta_e2000"]["patches"].items()]
        emit(format_table(rows, ["patch", "dE2000"], digits=2))
        emit(f"mean dE2000 {report['delta_e2000']['mean']:.3f}, max {report['delta_e2000']['max']:.3f} "
             f"(reference: the chart's spectra under {illuminant}, CIE 1931 2 deg, sRGB D65)")
    emit("ISP seconds: " + ", ".join(f"{k} {v:.3f}" for k, v in result.seconds.items())
         + f"; total {report['seconds']:.2f} s")
    for f in files:
        emit(f"wrote {f}")
    return 0


def _read_irradiance(path_text: str):
    from ..errors import LensrtError
    path = Path(path_text)
    if path.suffix.lower() == ".exr":
        from ..io.exr import read_spectral_exr
        E, wl, meta = read_spectral_exr(path)
        bw = meta.get("lensrt:bin_width_nm")
        return E, wl, (float(bw) if bw is not None else None)
    if path.suffix.lower() == ".npz":
        if not path.is_file():
            raise LensrtError(f"no such file {path}")
        return _read_npz(path)
    raise LensrtError(f"irradiance file {path} must be .exr or .npz")


def _read_npz(path: Path):
    """(irradiance, wavelength_nm, bin width or None) from an .npz file, every problem one error line."""
    import zipfile
    import numpy as np
    from ..errors import LensrtError
    need = "an .npz needs arrays 'irradiance' (rows, cols, n) and 'wavelength_nm' (n,)"
    try:
        with np.load(path, allow_pickle=False) as data:
            if not hasattr(data, "files") or "irradiance" not in data.files or "wavelength_nm" not in data.files:
                raise LensrtError(need, path=path)
            E, wl = np.asarray(data["irradiance"]), np.asarray(data["wavelength_nm"])
            bw = np.asarray(data["bin_width_nm"]) if "bin_width_nm" in data.files else None
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as err:
        raise LensrtError(f"not a readable .npz file ({type(err).__name__}: {err})", path=path,
                          hint=need) from None
    if E.ndim != 3 or wl.ndim != 1 or E.shape[-1] != wl.size or E.dtype.kind not in "fiu" or wl.dtype.kind not in "fiu":
        raise LensrtError(f"arrays of shapes {E.shape} and {wl.shape}: {need}", path=path)
    if not (np.isfinite(E).all() and (E >= 0).all() and np.isfinite(wl).all() and (wl > 0).all()):
        raise LensrtError("irradiance and wavelengths must be finite and non-negative", path=path)
    if bw is not None and not (bw.size == 1 and np.isfinite(bw).all() and float(bw) > 0):
        raise LensrtError("bin_width_nm must be one positive number", path=path)
    return E, wl, (None if bw is None else float(bw))


def _calibration_for_dng(sensor):
    from ..isp import calibrate
    return calibrate(sensor, "D65")  # DNG ColorMatrix1 is given for CalibrationIlluminant1 = D65


def _write_outputs(args, sensor, raw, result) -> list[str]:
    files = []
    meta = {"lensrt:sensor": sensor.name, "lensrt:iso": raw.iso, "lensrt:exposure_s": raw.exposure_s}
    if args.raw and Path(args.raw).suffix.lower() == ".dng":
        import numpy as np
        from ..io.dng import write_dng
        wb = np.asarray(result.wb_multipliers, float)
        cal = _calibration_for_dng(sensor)
        xyz_to_cam = np.diag(1.0 / wb) @ np.linalg.inv(cal.camera_to_xyz)
        files.append(str(write_dng(args.raw, raw, xyz_to_cam / xyz_to_cam.max(), 1.0 / wb)))
    elif args.raw:
        from ..io.raw import write_raw_exr
        files.append(str(write_raw_exr(args.raw, raw)))
    if args.out:
        from ..io.png import write_png
        files.append(str(write_png(args.out, result.to_uint8(), 8, {"Software": "lensrt", "Comment": str(meta)})))
    if args.out16:
        from ..io.png import write_image
        files.append(str(write_image(args.out16, result.to_uint16(), 16, {"Software": "lensrt"})))
    if args.linear:
        from ..io.exr import write_image_exr
        files.append(str(write_image_exr(args.linear, result.linear, metadata={**meta, "lensrt:colourspace": "linear sRGB (D65)"})))
    if args.hist:
        from ..views.plots.sensor import plot_histograms
        from ..isp import output_histograms, raw_histograms
        files.append(str(plot_histograms(raw_histograms(raw), output_histograms(result.to_uint8()), args.hist)))
    return files
