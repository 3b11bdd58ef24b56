"""Build a lens report: run every section (each one's failure stays in its section), then write
``report.json`` and ``index.html`` into the output folder."""
from __future__ import annotations

import datetime as _dt
import platform
import sys
import time
import traceback
import warnings
from pathlib import Path
from typing import Any, Callable, Sequence

from ..core.telemetry import measure
from ..errors import LensrtError
from ..io.paths import output_dir
from ..prescription.configurations import MultiConfigLens
from ..views.plots.figure import deferred_figures
from .model import Report, ReportContext, Section
from .kernel_plan import start_preload
from .options import ReportOptions, prepare_lens

__all__ = ["SECTIONS", "Report", "build_report", "section_keys"]


#: (key, title on the page, label on the terminal, module:function) of every section, in page order
SECTIONS: tuple[tuple[str, str, str, str], ...] = (
    ("lens", "Prescription and layout", "prescription and layout", "sections_lens:lens_section"),
    ("first_order", "First-order data beside real rays", "first-order data, real rays (compare)",
     "sections_lens:first_order_section"),
    ("aberrations", "Paraxial against real: distortion, focus, spherical aberration, colour",
     "distortion, focus, colour", "sections_compare:aberrations_section"),
    ("image_quality", "Spots, ray fans, pupils and relative illumination", "spots, fans, illumination",
     "sections_compare:image_quality_section"),
    ("zoom", "Configurations and focus breathing", "configurations, focus breathing",
     "sections_zoom:zoom_section"),
    ("psf", "PSF map", "PSF map", "sections_psf:psf_section"),
    ("mtf", "MTF", "MTF", "sections_psf:mtf_section"),
    ("bokeh", "Bokeh", "bokeh map", "sections_bokeh:bokeh_section"),
    ("dof", "Depth of field and hyperfocal distance", "depth of field", "sections_bokeh:dof_section"),
)


def section_keys() -> list[str]:
    return [s[0] for s in SECTIONS]


def _function(spec: str) -> Callable[[ReportContext, Section], None]:
    from importlib import import_module
    module, name = spec.split(":")
    return getattr(import_module(f"{__package__}.{module}"), name)



def _environment(command_line: str) -> dict[str, Any]:
    from importlib.metadata import PackageNotFoundError, version
    try:
        lensrt_version = version("lensrt")
    except PackageNotFoundError:  # running from a source tree that was never installed
        lensrt_version = None
    env: dict[str, Any] = {"lensrt": lensrt_version, "python": platform.python_version(),
                           "platform": platform.platform(), "machine": platform.machine(),
                           "command_line": command_line,
                           "date_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")}
    for mod in ("numpy", "warp", "matplotlib"):
        m = sys.modules.get(mod)
        env[mod] = getattr(m, "__version__", None) if m is not None else None
    return env


def _lens_summary(lens) -> dict[str, Any]:
    import math

    from ..paraxial import first_order
    fo = first_order(lens, None, math.inf)
    f = lens.fields
    full = (f"{2 * math.degrees(f.max_radial):.1f} deg" if f.kind == "angle" else f"{2 * f.max_radial:.1f} mm")
    return {"efl_mm": fo.efl_mm, "f_number": fo.f_number, "full_field": full, "surfaces": lens.n_surfaces,
            "object": "infinity" if math.isinf(lens.object_distance_mm) else f"{lens.object_distance_mm:g} mm",
            "length_mm": lens.length_mm}


def _lens_file_text(path) -> str:
    """A library lens by its name, any other file by its path."""
    from ..library import library_dir
    if not path:
        return "-"
    p = Path(path).resolve()
    try:
        if p.parent == library_dir().resolve():
            return f"{p.stem} (lensrt's lens library, {p.name})"
    except Exception:  # noqa: BLE001 - a missing library folder is no reason to fail here
        pass
    return str(path)


def build_report(lens, out_dir: str | Path, options: ReportOptions | None = None, *,
                 skip: Sequence[str] = (), stream=None, quiet: bool = False) -> Report:
    """Run the report's sections on ``lens`` and write ``index.html`` and ``report.json`` into ``out_dir``.

    ``lens`` may be a :class:`~lensrt.prescription.configurations.MultiConfigLens`: the
    ``zoom`` section then tabulates every configuration and the others analyse the
    current one.

    A section that raises keeps what it made so far and records the error (``Report.failed``);
    the others run on. Bad options or a lens that cannot be prepared raise :class:`LensrtError`
    before anything is written. Progress goes to ``stream`` (stderr) unless ``quiet``.
    """
    from .html import write_html
    from ..io.table import dumps_json
    options = options or ReportOptions()
    unknown = [k for k in skip if k not in section_keys()]
    if unknown:
        raise LensrtError(f"unknown section(s) {', '.join(unknown)} to skip", hint=f"use {', '.join(section_keys())}")
    with measure() as total:
        report = _run(lens, out_dir, options, skip, stream, quiet)
    report.telemetry = total.to_dict()
    report.telemetry["kernel_modules"] = report.kernel_modules
    report.json_path.write_text(dumps_json(report.to_dict()) + "\n")
    write_html(report, report.html_path)
    return report


def _figure_errors(outcomes, sections: list[Section]) -> None:
    """A figure or file that could not be made (by a worker process, nor then here): an error of the
    section that made it."""
    for owner, path, err in outcomes:
        if err is None:
            continue
        for sec in sections:
            if sec.key == owner:
                sec.errors.append(f"figure {Path(path).name} could not be drawn: {type(err).__name__}: {err} "
                                  "(a bug in lensrt; with LENSRT_FIGURE_WORKERS=0 report.json keeps its traceback)")


def _worker_trouble(renderer, sections: list[Section], stream, quiet: bool) -> None:
    """The renderer's one message (a worker process could not start, stopped, or failed a job, which then
    ran here): a warning of the first section with a job that ran here, and one line on ``stream``."""
    if not renderer.message:
        return
    owners = [j.owner for j in renderer.jobs if j.where == "caller"]
    for sec in sections:
        if sec.key in owners[:1]:
            sec.warnings.append(renderer.message)
    if not quiet:
        print(f"lensrt report: {renderer.message}", file=stream or sys.stderr)


def _module_loads(plan, loading) -> list[dict[str, Any]]:
    """The planned kernel modules and their loads (name, why, seconds, waited_s, error, skipped)."""
    if loading is None:
        return []
    loading.cancel()  # loads not started by now are of modules the report did not launch
    loads = loading.wait()
    return [{"module": p.name, "why": p.why, "seconds": ld.seconds, "waited_s": ld.waited_s, "error": ld.error,
             "skipped": ld.skipped} for p, ld in zip(plan, loads)]


def _run(lens, out_dir: str | Path, options: ReportOptions, skip: Sequence[str], stream, quiet: bool) -> Report:
    """Run the sections (each one measured) and gather the report; :func:`build_report` writes it.
    The figure worker processes start first, so that they have loaded Matplotlib by the first figure;
    after the last section the report gathers what needs no figure (kernel modules, key numbers) while the
    workers finish, and then waits only for the figures and files they have not."""
    from ..device import describe_device, resolve_device
    t0 = time.perf_counter()
    with deferred_figures() as renderer:
        family = None
        if isinstance(lens, MultiConfigLens):
            family, lens = lens, lens.configuration()
        analysed, notes = prepare_lens(lens, options)
        device = resolve_device(options.device)
        out = output_dir(out_dir)
        plan, loading = start_preload(analysed, options, device, skip)  # compile the kernels side by side, from now
        ctx = ReportContext(analysed, lens, options, out, device, notes)
        if family is not None:
            ctx.cache["configurations"] = family
        sections = _sections(ctx, skip, stream, quiet, renderer)
        report = Report(lens.name or str(lens.path), options, sections, out, device, describe_device(device),
                        0.0, {}, notes, _lens_summary(analysed))
        report.kernel_modules = _module_loads(plan, loading)
        _key_numbers(report, ctx)
        if renderer is not None:  # figures and files made by worker processes: they exist from here on
            outcomes = renderer.wait()
            _figure_errors(outcomes, sections)
            _worker_trouble(renderer, sections, stream, quiet)
            report.summary["figure_telemetry"] = renderer.stats()
            if any(err is not None for _, _, err in outcomes):
                _key_numbers(report, ctx)  # a section that failed by its figure shows no headline number
    report.environment = _environment(options.command_line)  # after the wait: the modules the report loaded
    report.summary["path"] = str(lens.path) if lens.path else None
    report.summary["lens_file"] = _lens_file_text(lens.path)
    report.summary["source"] = lens.source
    report.seconds = time.perf_counter() - t0
    report.json_path = out / "report.json"
    report.html_path = out / "index.html"
    return report


def _key_numbers(report: Report, ctx: ReportContext) -> None:
    """The report's headline numbers (a failure here is noted in its summary, never the report's)."""
    report.summary.pop("key_numbers_error", None)
    try:
        from .key_numbers import key_numbers
        report.key_numbers = key_numbers(ctx, report.sections)
    except Exception as err:  # noqa: BLE001 - the headline numbers are a convenience, never a failure
        report.summary["key_numbers_error"] = f"{type(err).__name__}: {err}"


def _sections(ctx: ReportContext, skip: Sequence[str], stream, quiet: bool, renderer) -> list[Section]:
    """Run every section not skipped, each measured, its warnings and errors kept; progress on ``stream``."""
    from ..views.progress import StepProgress
    steps = StepProgress(len([s for s in SECTIONS if s[0] not in skip]), stream, quiet)
    sections = []
    for key, title, label, spec in SECTIONS:
        sec = Section(key, title)
        sections.append(sec)
        if key in skip:
            sec.data["skipped"] = True
            continue
        ctx.progress = steps.start(label)
        if renderer is not None:
            renderer.owner = key
        t_sec = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught, measure() as rec:
            warnings.simplefilter("always")
            try:
                _function(spec)(ctx, sec)
            except LensrtError as err:
                sec.errors.append(str(err))
            except Exception as err:  # noqa: BLE001 - a failing section must not take the report with it
                sec.errors.append(f"internal error: {type(err).__name__}: {err} (a bug in lensrt; the traceback is "
                                  "in report.json)")
                sec.traceback = traceback.format_exc()
        sec.warnings = list(dict.fromkeys(str(w.message) for w in caught
                                          if not issubclass(w.category, DeprecationWarning)))
        sec.seconds = time.perf_counter() - t_sec
        sec.telemetry = rec.to_dict()
        note = sec.errors[0][:100] if not sec.ok else \
            (f"{len(sec.warnings)} warning{'s' * (len(sec.warnings) > 1)} on the page" if sec.warnings else "")
        steps.finish(sec.ok, note)
    return sections
