"""Figure and file jobs handed to worker processes as data (lensrt.views.plots.figure: drawn_by_workers, defer):
the files a worker writes are those the caller writes, the caller builds no figure (Matplotlib's figure code is
never imported there), a worker that stops or cannot start hands its jobs back to the caller with one message,
and no worker process outlives its block."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from lensrt.io.exr import read_exr, write_exr
from lensrt.io.table import write_json
from lensrt.views.plots import figure as F
from lensrt.views.plots.figure import deferred_figures, defer
from lensrt.views.plots import psf as F_psf
from lensrt.views.plots.psf import PsfTile, draw_psf_mosaic, plot_mtf_curves

ROOT = Path(__file__).resolve().parents[2]


def _tiles(n: int = 6) -> list[PsfTile]:
    """Gaussian PSFs of growing width at image points on a line (mm), on 40 x 40 grids of 2.5 um."""
    out = []
    u = (np.arange(40) - 19.5) * 0.0025
    for k in range(n):
        x, y = 3.0 * k, -1.0 * k
        s = 0.004 * (1 + k)
        img = np.exp(-(u[None, :] ** 2 + u[:, None] ** 2) / (2 * s * s))
        out.append(PsfTile(img, (x + u[0] - 0.00125, x + u[-1] + 0.00125, y + u[0] - 0.00125, y + u[-1] + 0.00125),
                           (x, y)))
    return out


def _let_workers_take_their_jobs(renderer) -> None:
    """Until every job is in a worker's hands: then :meth:`FigureRenderer.wait` has nothing left to take back."""
    while renderer.todo.qsize():
        time.sleep(0.01)


def _make_all(d: Path) -> dict[str, Path]:
    """Two figures and two data files, through the functions the report uses."""
    f = np.linspace(0.0, 200.0, 41)
    curves = [("axis", np.exp(-f / 150), np.exp(-f / 120)), ("corner", np.exp(-f / 90), np.exp(-f / 60))]
    out = {"mosaic": draw_psf_mosaic(d / "mosaic.png", _tiles(), 3, True, "six Gaussian tiles"),
           "mtf": plot_mtf_curves(d / "mtf.png", f, curves, diffraction=np.clip(1 - f / 220, 0, 1),
                                  nyquist_cpmm=100.0, title="two fields")}
    rng = np.random.default_rng(7)
    out["exr"] = d / "map.exr"
    defer(write_exr, out["exr"], {"f0.psf": rng.random((16, 24)).astype(np.float32),
                                  "f0.stderr": rng.random((16, 24)).astype(np.float32)},
          {"lensrt:kind": "test", "lensrt:values": [1, 2.5, None]})
    out["json"] = d / "data.json"
    defer(write_json, out["json"], {"x": np.arange(3), "y": 0.1, "z": float("nan")})
    return out


def test_jobs_in_a_worker_write_the_files_the_caller_writes(tmp_path):
    from PIL import Image
    here = _make_all(tmp_path / "here")
    with deferred_figures(1) as renderer:
        there = _make_all(tmp_path / "worker")
        _let_workers_take_their_jobs(renderer)
        outcomes = renderer.wait()
    assert [e for _, _, e in outcomes] == [None] * 4 and renderer.message is None
    assert renderer.stats()["jobs_in_workers"] == 4
    for k in here:
        assert there[k].read_bytes() == here[k].read_bytes(), k
    # a figure's pixel size is its size in inches times its dpi (120): 3 x 2 tiles of 1.6 in plus margins
    assert Image.open(there["mosaic"]).size == (round((1.6 * 3 + 0.4) * 120), round((1.6 * 2 + 0.6) * 120))
    assert Image.open(there["mtf"]).size == (round(6.4 * 120), round(4.2 * 120))
    assert read_exr(there["exr"])[1]["lensrt:values"] == "[1, 2.5, null]"
    assert json.loads(there["json"].read_text()) == {"x": [0, 1, 2], "y": 0.1, "z": None}


def test_the_caller_builds_no_figure(tmp_path):
    """With a worker, a report's plot function pickles its data: Matplotlib's figure and Agg code stay out of
    the calling process, and the file exists once the block has ended."""
    code = ("import sys, numpy as np\n"
            "from lensrt.views.plots.figure import deferred_figures\n"
            "from lensrt.views.plots.psf import plot_mtf_curves\n"
            "with deferred_figures(1):\n"
            "    plot_mtf_curves(sys.argv[1], np.linspace(0, 1, 5), [('a', np.ones(5), np.ones(5))])\n"
            "    print(sorted(m for m in ('matplotlib.figure', 'matplotlib.backends.backend_agg') if m in sys.modules))\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT)] + [v for v in [os.environ.get("PYTHONPATH")] if v]))
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "m.png")], capture_output=True, text=True,
                         env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
    assert (tmp_path / "m.png").stat().st_size > 5000


def test_a_worker_that_stops_hands_its_jobs_to_the_caller(tmp_path):
    with deferred_figures(1) as renderer:
        proc = renderer.workers[0].proc
        first = _make_all(tmp_path / "a")
        proc.kill()
        proc.wait()
        second = _make_all(tmp_path / "b")
        outcomes = renderer.wait()
    assert [e for _, _, e in outcomes] == [None] * 8
    assert renderer.message.startswith("a figure worker process stopped")
    assert "ran in this process instead" in renderer.message
    for p in list(first.values()) + list(second.values()):
        assert p.stat().st_size > 0
    assert second["mosaic"].read_bytes() == first["mosaic"].read_bytes()


def test_a_worker_that_cannot_start_leaves_the_work_to_the_caller(tmp_path, monkeypatch):
    def no_process(*args, **kwargs):
        raise OSError("no more processes")
    monkeypatch.setattr(subprocess, "Popen", no_process)
    with deferred_figures(2) as renderer:
        assert renderer.workers == []
        paths = _make_all(tmp_path)
        assert all(p.stat().st_size > 0 for p in paths.values())  # written at once, in this process
        renderer.wait()
    assert renderer.message.startswith("could not start a figure worker process (OSError: no more processes)")


def test_a_job_that_fails_everywhere_is_its_error(tmp_path):
    with deferred_figures(1) as renderer:
        defer(write_exr, tmp_path / "bad.exr", {"x": np.zeros((2, 2), np.int8)})  # no EXR pixel type
        _let_workers_take_their_jobs(renderer)
        plot_mtf_curves(tmp_path / "good.png", np.linspace(0, 1, 5), [("a", np.ones(5), np.ones(5))])
        (_, p1, e1), (_, p2, e2) = renderer.wait()
    assert "int8 has no EXR pixel type" in str(e1) and not p1.exists()
    assert e2 is None and p2.stat().st_size > 0
    assert renderer.message.startswith("a figure worker process could not draw bad.exr")


def test_the_end_takes_file_jobs_back_from_a_busy_worker(tmp_path):
    """At the wait the caller writes the files still queued behind a busy worker (it would sit idle), and leaves
    the figures queued there to the worker."""
    from lensrt.views.plots.figure_worker import job_bytes
    with deferred_figures(1) as renderer:
        renderer.submit(job_bytes(time.sleep, (2.0,), {}), tmp_path / "busy")  # the worker's hands are full
        _let_workers_take_their_jobs(renderer)
        paths = _make_all(tmp_path)
        outcomes = renderer.wait()
    stats = renderer.stats()
    assert [e for _, _, e in outcomes] == [None] * 5 and renderer.message is None
    assert stats["stolen"] == 2 and stats["jobs_in_workers"] == 3
    assert [(j.path.name, j.where) for j in renderer.jobs] == [
        ("busy", "worker"), ("mosaic.png", "worker"), ("mtf.png", "worker"), ("map.exr", "stolen"),
        ("data.json", "stolen")]
    assert sorted(stats["waited_for"]) == ["busy", "data.json", "map.exr", "mosaic.png", "mtf.png"]
    assert all(p.stat().st_size > 0 for p in paths.values())


def test_no_worker_process_outlives_its_block(tmp_path):
    with deferred_figures(2) as renderer:
        procs = [w.proc for w in renderer.workers]
        _make_all(tmp_path / "ok")
    assert len(procs) == 2 and all(p.poll() is not None for p in procs)
    with pytest.raises(KeyError):
        with deferred_figures(2) as renderer:
            procs = [w.proc for w in renderer.workers]
            _make_all(tmp_path / "failing")
            raise KeyError("the caller fails")
    assert all(p.poll() is not None for p in procs)  # stopped without waiting for their jobs
    assert F._active is None



def test_exr_bytes_do_not_depend_on_openexr_threads(tmp_path):
    """A worker on a large machine compresses EXRs with 4 threads (figure_worker.warm_up): the same file."""
    import OpenEXR
    rng = np.random.default_rng(3)
    img = np.zeros((300, 200), np.float32)
    img[100:180, 40:150] = rng.random((80, 110))
    chans = {"XYZ.X": img, "XYZ.Y": 2 * img, "noise.Y_rel_stderr": img[::-1].copy()}
    before = OpenEXR.global_thread_count()
    try:
        for n in (0, 4):
            OpenEXR.set_global_thread_count(n)
            write_exr(tmp_path / f"t{n}.exr", chans, {"lensrt:kind": "test"})
    finally:
        OpenEXR.set_global_thread_count(before)
    assert (tmp_path / "t0.exr").read_bytes() == (tmp_path / "t4.exr").read_bytes()


def test_a_call_that_cannot_be_pickled_runs_in_the_caller(tmp_path):
    from types import MappingProxyType
    chans = MappingProxyType({"R": np.ones((4, 4), np.float32)})  # pickle refuses a mappingproxy
    with deferred_figures(1) as renderer:
        defer(write_exr, tmp_path / "here.exr", chans)
        assert (tmp_path / "here.exr").stat().st_size > 0 and renderer.jobs == []
    assert np.array_equal(read_exr(tmp_path / "here.exr")[0]["R"], chans["R"])


def test_the_message_says_why_a_worker_stopped(tmp_path, monkeypatch):
    fake = tmp_path / "python"
    fake.write_text("#!/bin/sh\necho 'ModuleNotFoundError: No module named matplotlib' >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setattr(sys, "executable", str(fake))
    with deferred_figures(1) as renderer:
        paths = _make_all(tmp_path / "out")
        renderer.wait()
    assert "it said: ModuleNotFoundError: No module named matplotlib" in renderer.message
    assert renderer.message.startswith("a figure worker process stopped")
    assert all(p.stat().st_size > 0 for p in paths.values())


def _held_until(flag: Path) -> bytes:
    """A job that keeps its worker busy until ``flag`` exists (a shell loop: no test code in the worker)."""
    from lensrt.views.plots.figure_worker import job_bytes
    return job_bytes(subprocess.run, (["sh", "-c", f'while [ ! -e "{flag}" ]; do sleep 0.02; done'],),
                     {"check": True, "timeout": 120})


def _until(condition, what: str) -> None:
    deadline = time.monotonic() + 120
    while not condition():
        assert time.monotonic() < deadline, f"never happened: {what}"
        time.sleep(0.01)


def test_a_free_worker_takes_the_next_job(tmp_path):
    """Jobs wait in one queue: a figure submitted while one worker is held goes to the other worker once that is
    free, not in line behind the held one."""
    from lensrt.views.plots.figure_worker import job_bytes
    flag = tmp_path / "go"
    with deferred_figures(2) as renderer:
        renderer.submit(_held_until(flag), tmp_path / "held")
        renderer.submit(job_bytes(time.sleep, (0.05,), {}), tmp_path / "short")
        _until(lambda: renderer.todo.qsize() == 0, "both workers took a job")
        mosaic = draw_psf_mosaic(tmp_path / "mosaic.png", _tiles(), 3, False, "six tiles")
        figure = renderer.jobs[-1]
        _until(lambda: figure.done or figure.error is not None, "the figure was drawn")
        assert not renderer.jobs[0].done  # drawn while the held worker is still held
        flag.touch()
        outcomes = renderer.wait()
    assert [e for _, _, e in outcomes] == [None] * 3 and renderer.message is None
    assert mosaic.stat().st_size > 0 and figure.where == "worker"


def test_figures_go_to_the_workers_before_files(tmp_path):
    """Queued figures (which only a worker draws) are taken before queued files (which the caller takes back at
    the end), each kind in submission order."""
    flag = tmp_path / "go"
    with deferred_figures(1) as renderer:
        renderer.submit(_held_until(flag), tmp_path / "held")
        _until(lambda: renderer.todo.qsize() == 0, "the worker took the held job")
        paths = _make_all(tmp_path / "out")  # mosaic, mtf (figures), then exr, json (files)
        order = [j.path.name for j in renderer.jobs[1:]]
        flag.touch()
        _until(lambda: all(j.done for j in renderer.jobs), "every job done")
        renderer.wait()
    assert order == ["mosaic.png", "mtf.png", "map.exr", "data.json"]
    started = sorted(renderer.jobs[1:], key=lambda j: j.started)
    assert [j.path.name for j in started] == ["mosaic.png", "mtf.png", "map.exr", "data.json"]
    assert all(j.where == "worker" for j in renderer.jobs) and all(p.stat().st_size > 0 for p in paths.values())


@pytest.mark.parametrize("cores, workers", [(1, 0), (2, 0), (3, 0), (4, 2), (11, 2), (12, 3), (16, 3), (32, 4),
                                            (128, 4)])
def test_the_worker_count_follows_the_cores(cores, workers, monkeypatch):
    monkeypatch.delenv("LENSRT_FIGURE_WORKERS", raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: cores)
    assert F.figure_workers() == workers == F.default_figure_workers(cores)
    monkeypatch.setenv("LENSRT_FIGURE_WORKERS", "5")
    assert F.figure_workers() == 5


def test_the_psf_mosaic_draws_each_tile_in_its_box(tmp_path):
    """The fixed-position mosaic: tiles inside the figure, apart, each with room for its title; every tile's PSF
    (a Gaussian peaked on its reference point, drawn peak-normalised) is brightest at its box's centre, and the
    cells without a tile stay blank."""
    from PIL import Image
    boxes = F_psf.mosaic_axes_boxes(3, 3)
    assert len(boxes) == 9
    for i, (l, b, w, h) in enumerate(boxes):
        assert 0 < l and l + w < 1 and 0 < b and b + h < 1
        for (l2, b2, w2, h2) in boxes[i + 1:]:
            assert l + w <= l2 or l2 + w2 <= l or b + h <= b2 or b2 + h2 <= b  # no two overlap
    for lines in (1, 2, 3):  # a longer title: the tiles and their labels stay below it, inside the figure
        h_in = 1.6 * 7 + 0.6
        more = F_psf.mosaic_axes_boxes(7, 7, lines)
        assert min(b for _, b, _, _ in more) > 0
        assert max(b + h for _, b, _, h in more) * h_in + 0.17 <= h_in - 0.19 * lines
    tiles = _tiles(7)
    path = draw_psf_mosaic(tmp_path / "m.png", tiles, 3, False, "seven tiles")
    img = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64)
    rows, cols = img.shape[:2]
    assert (cols, rows) == (round((1.6 * 3 + 0.4) * 120), round((1.6 * 3 + 0.6) * 120))
    for k, (l, b, w, h) in enumerate(boxes):
        # the box in pixels (rows from the top), its central half (away from the scale bar and the frame)
        r0, r1 = round((1 - b - h) * rows), round((1 - b) * rows)
        c0, c1 = round(l * cols), round((l + w) * cols)
        inner = img[r0 + (r1 - r0) // 4:r1 - (r1 - r0) // 4, c0 + (c1 - c0) // 4:c1 - (c1 - c0) // 4]
        if k < len(tiles):
            lum = inner.sum(axis=2)
            r, c = np.nonzero(lum >= lum.max() - 1)  # the peak's pixels (the PSF's brightest cells)
            centre = (inner.shape[0] - 1) / 2, (inner.shape[1] - 1) / 2
            assert abs(r.mean() - centre[0]) <= 1.5 and abs(c.mean() - centre[1]) <= 1.5, (k, r, c, centre)
            corner = img[r0 + 5:r0 + 10, c1 - 10:c1 - 5].sum(axis=2)  # top right, inside the frame
            assert corner.max() < lum.max() / 2  # the PSF's dim surround
        else:
            assert np.all(img[r0:r1, c0:c1] == 255)  # no axes drawn in an empty cell
