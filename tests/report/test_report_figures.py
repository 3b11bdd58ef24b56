"""The report's figures and files when worker processes make them (lensrt.views.plots.figure): every file the
same as when the report's own process makes them (PNG pixels and text, EXR channels and attributes, JSON
numbers; timings aside), every figure there with its size, no worker process left behind, and a worker that
cannot start costs time, not figures, with one message."""
from __future__ import annotations

import importlib.util
import io
import os
import subprocess
from pathlib import Path

import pytest

from lensrt import load_lens
from lensrt.report import ReportOptions, build_report

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]


def _compare_files():
    spec = importlib.util.spec_from_file_location("compare_report_files",
                                                  ROOT / "benchmarks" / "compare_report_files.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _children() -> list[int]:
    """Process ids whose parent is this process (Linux /proc)."""
    me, out = os.getpid(), []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == me:
                out.append(int(d.name))
    return out


def _report(out: Path, workers: str, skip: list[str], monkeypatch):
    monkeypatch.setenv("LENSRT_FIGURE_WORKERS", workers)
    options = ReportOptions(quality="normal", device="cpu", ray_fraction=1 / 64)
    stream = io.StringIO()
    report = build_report(load_lens(None), out, options, skip=skip, stream=stream)
    return report, stream.getvalue()


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="counts child processes through /proc")
def test_worker_files_equal_those_of_the_report_process(tmp_path, monkeypatch):
    from PIL import Image
    skip = ["first_order", "zoom", "mtf"]
    before = set(_children())
    here, _ = _report(tmp_path / "w0", "0", skip, monkeypatch)
    there, _ = _report(tmp_path / "w2", "2", skip, monkeypatch)
    assert not here.failed and not there.failed
    assert set(_children()) <= before  # the workers are gone (and reaped) when the report returns
    stats = there.summary["figure_telemetry"]
    # every job ran in a worker, or (a file still queued at the end) was taken back by the report's process
    assert stats["workers"] == 2 and stats["jobs"] == stats["jobs_in_workers"] + stats["stolen"] >= 14
    assert not [w for s in there.sections for w in s.warnings if "figure worker" in w]
    cmp = _compare_files()
    names = sorted(p.name for p in (tmp_path / "w0").iterdir() if p.suffix in (".png", ".exr", ".json"))
    assert names == sorted(p.name for p in (tmp_path / "w2").iterdir() if p.suffix in (".png", ".exr", ".json"))
    assert {"layout.png", "spots.png", "psf.png", "psf.exr", "psf.json", "bokeh_map.png", "bokeh_map.exr",
            "bokeh_map.json"} <= set(names)
    kinds = {".png": cmp.compare_png, ".exr": cmp.compare_exr, ".json": cmp.compare_json}
    for name in names:
        a, b = tmp_path / "w0" / name, tmp_path / "w2" / name
        assert b.stat().st_size > 0
        assert kinds[b.suffix](a, b) == [], name
        if b.suffix == ".png" and name != "bokeh_map.png":  # Matplotlib figures: drawn by the same code
            assert a.read_bytes() == b.read_bytes(), name
    # the bokeh picture has the map's pixels (1.5 : 1 sensor); the PSF mosaic one 1.6 in tile per field
    w, h = Image.open(tmp_path / "w2" / "bokeh_map.png").size
    assert w / h == pytest.approx(1.5, rel=0.01)
    rows, cols = next(s for s in there.sections if s.key == "psf").data["psf_map"]["grid"]
    assert Image.open(tmp_path / "w2" / "psf.png").size == (round((1.6 * cols + 0.4) * 120),
                                                              round((1.6 * rows + 0.6) * 120))


def test_a_worker_that_cannot_start_costs_time_not_figures(tmp_path, monkeypatch):
    def no_process(*args, **kwargs):
        raise OSError("no more processes")
    monkeypatch.setattr(subprocess, "Popen", no_process)
    skip = ["first_order", "image_quality", "zoom", "psf", "mtf", "bokeh", "dof"]
    report, printed = _report(tmp_path, "2", skip, monkeypatch)
    assert not report.failed
    for name in ("layout.png", "field_curvature_distortion.png", "longitudinal.png"):
        assert (tmp_path / name).stat().st_size > 5000
    messages = [w for s in report.sections for w in s.warnings if "figure worker" in w]
    assert len(messages) == 1 and messages[0].startswith("could not start a figure worker process")
    assert printed.count("could not start a figure worker process") == 1
