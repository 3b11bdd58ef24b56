"""Figures drawn by worker processes (lensrt.views.plots.figure.deferred_figures): the same files as a
direct savefig, errors handed back per figure, a bad LENSRT_FIGURE_WORKERS refused, and a report whose
figures are drawn by a worker equal to one drawn in the calling process."""
from __future__ import annotations

import json

import numpy as np
import pytest

from lensrt.errors import LensrtError
from lensrt.views.plots.figure import deferred_figures, figure_workers, new_figure, save_figure


def _figure(seed: int):
    rng = np.random.default_rng(seed)
    fig = new_figure(4, 3)
    ax = fig.add_subplot()
    ax.plot(np.cumsum(rng.standard_normal(200)), label=f"walk {seed}")
    ax.imshow(rng.random((20, 30)), extent=(0, 200, -5, 5), aspect="auto", alpha=0.3)
    ax.set_title("a title with $\\lambda$ = 587.6 nm")
    ax.legend()
    return fig


def test_workers_write_the_same_files_as_savefig(tmp_path):
    for k in range(3):
        _figure(k).savefig(tmp_path / f"direct{k}.png")
    with deferred_figures(2) as renderer:
        paths = [save_figure(_figure(k), tmp_path / "sub" / f"worker{k}.png") for k in range(3)]
        outcomes = renderer.wait()
    assert [p for _, p, _ in outcomes] == paths
    assert all(err is None for _, _, err in outcomes)
    for k in range(3):
        assert (tmp_path / "sub" / f"worker{k}.png").read_bytes() == (tmp_path / f"direct{k}.png").read_bytes()


def test_a_figure_that_cannot_be_drawn_comes_back_as_its_error(tmp_path):
    bad = new_figure(2, 2)
    bad.text(0.5, 0.5, r"$\frac{$")  # mathtext fails when the figure is drawn, not when it is made
    with deferred_figures(1) as renderer:
        renderer.owner = "first"
        save_figure(_figure(0), tmp_path / "good.png")
        renderer.owner = "second"
        save_figure(bad, tmp_path / "bad.png")
        outcomes = renderer.wait()
    (o1, p1, e1), (o2, p2, e2) = outcomes
    assert (o1, e1) == ("first", None) and p1.stat().st_size > 0
    assert o2 == "second" and isinstance(e2, RuntimeError) and "ValueError" in str(e2)


def test_no_workers_draws_in_the_caller(tmp_path, monkeypatch):
    monkeypatch.setenv("LENSRT_FIGURE_WORKERS", "0")
    with deferred_figures() as renderer:
        assert renderer is None
        p = save_figure(_figure(1), tmp_path / "now.png")
        assert p.stat().st_size > 0  # written before the block ends


@pytest.mark.parametrize("raw", ["two", "-1", "1.5"])
def test_bad_worker_count_is_one_clear_error(monkeypatch, raw):
    monkeypatch.setenv("LENSRT_FIGURE_WORKERS", raw)
    with pytest.raises(LensrtError, match="LENSRT_FIGURE_WORKERS"):
        figure_workers()


@pytest.mark.slow
def test_report_figures_from_a_worker_equal_those_drawn_in_process(tmp_path, monkeypatch):
    from lensrt.cli import main
    skip = [a for k in ("first_order", "zoom", "psf", "mtf", "bokeh", "dof") for a in ("--skip", k)]
    runs = {}
    for n in ("0", "1"):
        monkeypatch.setenv("LENSRT_FIGURE_WORKERS", n)
        d = tmp_path / f"w{n}"
        assert main(["report", "--out", str(d), "--quality", "draft", "--device", "cpu", "--quiet"] + skip) == 0
        runs[n] = d
    files = json.loads((runs["1"] / "report.json").read_text())["files"]
    pngs = [f for f in files if f.endswith(".png")]
    assert len(pngs) >= 8  # layout, distortion, fans, spots, pupils, relative illumination ...
    for f in pngs:
        assert (runs["1"] / f).read_bytes() == (runs["0"] / f).read_bytes(), f
