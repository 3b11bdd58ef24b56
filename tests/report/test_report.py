"""``lensrt report``: two library lenses on the CPU at draft quality -- every figure and data file
exists, is not empty and is linked from the page (and every link resolves); the page needs no
network; report.json holds every Monte Carlo figure's samples, seconds and standard error; a
failing section stays in its section; and headless Chromium renders the page with no broken image.

Chromium: Debian's ``chromium`` package. The session fixture installs it with apt-get when it is
missing and the tests run as root (CI on a fresh Debian-like machine); otherwise those tests skip.
"""
from __future__ import annotations

import io
import json
import math
import os
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from lensrt.cli import main

CHROMIUM = "/usr/bin/chromium"

#: every file the draft report of a lens writes beside index.html
EXPECTED = {"layout.png", "field_curvature_distortion.png", "grid_distortion.png", "longitudinal.png", "spots.png",
            "ray_fans.png", "opd_fans.png", "relative_illumination.png", "pupils.png", "psf.png", "psf.exr",
            "psf.json", "mtf.png", "mtf_field.png", "mtf_system.png", "mtf.json", "bokeh_map.png", "bokeh_map.exr",
            "bokeh_map.json", "report.json"}

LENSES = {
    "dgauss_50mm_f2": [],
    "cooke_triplet_50mm_f5": ["--focus-m", "3", "--f-number", "8", "--sensor", "aps-c", "--seed", "3"],
}


class _Links(HTMLParser):
    """Every src/href on the page, and the tags that could fetch something."""

    def __init__(self) -> None:
        super().__init__()
        self.refs: list[tuple[str, str, str]] = []
        self.imgs: list[str] = []
        self.tags: list[tuple[str, dict]] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.append((tag, a))
        for k in ("src", "href"):
            if a.get(k) is not None:
                self.refs.append((tag, k, a[k]))
        if tag == "img":
            self.imgs.append(a.get("src", ""))


def _links(html_text: str) -> _Links:
    p = _Links()
    p.feed(html_text)
    return p


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    """The two draft reports, made through the CLI: {name: (folder, exit status)}."""
    base = tmp_path_factory.mktemp("reports")
    out = {}
    for name, extra in LENSES.items():
        d = base / name
        rc = main(["report", name, "--out", str(d), "--quality", "draft", "--device", "cpu", "--quiet"] + extra)
        out[name] = (d, rc)
    return out


def _strict_json(path: Path):
    def bad(token):
        raise ValueError(f"non-strict JSON token {token} in {path}")
    return json.loads(path.read_text(), parse_constant=bad)


@pytest.mark.parametrize("name", list(LENSES))
def test_every_file_exists_and_is_linked(reports, name):
    d, rc = reports[name]
    assert rc == 0
    page = (d / "index.html").read_text(encoding="utf-8")
    links = _links(page)
    targets = {v for _, _, v in links.refs if not v.startswith("#")}
    # every link is a relative file name in the folder, and the file is there and not empty
    for t in targets:
        assert "/" not in t and ":" not in t, f"link {t!r} is not a file beside the page"
        assert (d / t).is_file(), f"{t} is linked but missing"
        assert (d / t).stat().st_size > 0, f"{t} is empty"
    # every file written beside the page is linked from it, the expected ones among them
    written = {p.name for p in d.iterdir()} - {"index.html"}
    assert EXPECTED <= written
    assert written <= targets, f"written but not linked: {sorted(written - targets)}"
    # every figure is an image on the page (not only a link), and decodes to a non-blank picture
    from PIL import Image
    for png in sorted(p for p in written if p.endswith(".png")):
        assert png in links.imgs, f"{png} is not shown"
        with Image.open(d / png) as im:
            a = np.asarray(im.convert("L"), dtype=np.float64)
        assert a.shape[0] > 100 and a.shape[1] > 100 and a.std() > 1.0, png


@pytest.mark.parametrize("name", list(LENSES))
def test_page_needs_no_network(reports, name):
    d, _ = reports[name]
    page = (d / "index.html").read_text(encoding="utf-8")
    links = _links(page)
    assert not [v for _, _, v in links.refs if re.match(r"^(https?:)?//", v)]
    assert not [t for t, a in links.tags if t == "link" or (t == "script" and "src" in a)]
    assert "@import" not in page and "url(" not in page
    assert "<style>" in page  # the CSS is inline


@pytest.mark.parametrize("name", list(LENSES))
def test_report_json_and_monte_carlo_records(reports, name):
    d, _ = reports[name]
    data = _strict_json(d / "report.json")
    assert data["ok"] and not data["failed_sections"]
    assert [s["key"] for s in data["sections"]] == ["lens", "first_order", "aberrations", "image_quality", "zoom",
                                                    "psf", "mtf", "bokeh", "dof"]
    assert data["device"] == "cpu" and data["options"]["precision"] == "float32"
    assert data["environment"]["command_line"].startswith("lensrt report " + name)
    assert data["environment"]["lensrt"]
    figures = {m["figure"] for m in data["monte_carlo"]}
    assert {"spots.png", "relative_illumination.png", "psf.png", "mtf.png, mtf_field.png", "bokeh_map.png"} <= figures
    page = (d / "index.html").read_text(encoding="utf-8")
    for m in data["monte_carlo"]:
        assert m["samples"] > 0 and m["seconds"] > 0 and m["stderr"], m
        assert m["stderr_max"] is None or math.isfinite(m["stderr_max"])
        assert f"{m['samples']:,}" in page  # the Monte Carlo table shows it
    # telemetry: every section's launches, copies and seconds, and the whole report's, which holds them all
    for s in data["sections"]:
        assert {"wall_s", "kernel_s", "launches", "copies"} <= set(s), s["key"]
        assert min(s["launches"], s["copies"], s["wall_s"], s["kernel_s"]) >= 0
    total = data["telemetry"]
    assert total["launches"] >= sum(s["launches"] for s in data["sections"]) > 0
    assert total["copies"] >= sum(s["copies"] for s in data["sections"])
    # the PSF map's record is the sum over its field points, as psf.json says
    psf = _strict_json(d / "psf.json")
    rec = next(m for m in data["monte_carlo"] if m["figure"] == "psf.png")
    assert rec["samples"] == psf["rays_total"] == sum(f["samples"] for f in psf["fields"])


def test_options_reach_the_analyses(reports):
    """The Cooke report was made at f/8, focused at 3 m, on APS-C: the lens it analysed says so, and
    its depth-of-field row at 3 m is the Field Guide's formula (p. 23) with that lens's numbers."""
    from lensrt import load_lens
    from lensrt.paraxial import first_order
    from lensrt.paraxial.photographic import depth_of_field_mm, sensor_format
    from lensrt.report import ReportOptions, prepare_lens
    d, _ = reports["cooke_triplet_50mm_f5"]
    data = _strict_json(d / "report.json")
    assert data["summary"]["f_number"] == pytest.approx(8.0, rel=1e-9)
    sec = {s["key"]: s for s in data["sections"]}
    assert sec["first_order"]["data"]["first_order"]["object_distance_mm"] == pytest.approx(3000.0)
    assert sec["psf"]["data"]["psf_map"]["sensor"] == "aps-c"
    lens, _ = prepare_lens(load_lens("cooke_triplet_50mm_f5"), ReportOptions(object_distance_mm=3000.0, f_number=8.0))
    fo = first_order(lens, None, math.inf)
    c = sensor_format("aps-c").coc_mm
    dof = depth_of_field_mm(3000.0 + fo.entrance_pupil_z_mm, fo.front_focal_length_mm, 8.0, c,
                            fo.entrance_pupil_distance_mm)
    row = next(r for r in sec["dof"]["data"]["depth_of_field"]["against_focus"] if "report focus" in r["focus_m"])
    assert row["near_m"] == pytest.approx((dof.near_mm - fo.entrance_pupil_z_mm) / 1000.0, rel=1e-12)
    assert row["far_m"] == pytest.approx((dof.far_mm - fo.entrance_pupil_z_mm) / 1000.0, rel=1e-12)
    assert "f/8" in (d / "index.html").read_text(encoding="utf-8")


def test_prepare_lens_stops_down_and_focuses():
    """--f-number gives that paraxial f-number; --focus-m puts the paraxial image of the object plane on
    the image surface (unit focusing, p. 12), the lens file's own focus offset kept."""
    from lensrt import load_lens
    from lensrt.errors import LensrtError
    from lensrt.paraxial import first_order
    from lensrt.report import ReportOptions, prepare_lens
    base = load_lens("dgauss_50mm_f2")
    offset = base.image_z_mm - first_order(base).image_z_mm
    lens, notes = prepare_lens(base, ReportOptions(f_number=4.0, object_distance_mm=1500.0))
    assert first_order(lens, None, math.inf).f_number == pytest.approx(4.0, rel=1e-12)
    fo = first_order(lens)
    assert lens.object_distance_mm == 1500.0
    assert lens.image_z_mm - fo.image_z_mm == pytest.approx(offset, abs=1e-9)
    assert len(notes) == 2 and "f/4" in notes[0] and "1.5 m" in notes[1]
    with pytest.raises(LensrtError, match="wider than the lens opens"):
        prepare_lens(base, ReportOptions(f_number=1.4))
    same, notes = prepare_lens(base, ReportOptions())
    assert same is base and notes == []


def test_a_failing_section_stays_in_its_section(tmp_path, monkeypatch):
    """A bug in one section and a LensrtError in another: both say why on the page and in
    report.json, the other sections are made, and the exit status is 1."""
    import lensrt.report.sections_bokeh as sb
    from lensrt.errors import LensrtError

    def boom(ctx, sec):
        sec.text("made before the failure")
        raise RuntimeError("boom in the bokeh map")

    def refuse(ctx, sec):
        raise LensrtError("this lens has no depth of field", hint="try another")
    monkeypatch.setattr(sb, "bokeh_section", boom)
    monkeypatch.setattr(sb, "dof_section", refuse)
    d = tmp_path / "r"
    skip = [a for k in ("first_order", "aberrations", "image_quality", "psf", "mtf") for a in ("--skip", k)]
    rc = main(["report", "--out", str(d), "--quality", "draft", "--device", "cpu", "--quiet"] + skip)
    assert rc == 1
    data = _strict_json(d / "report.json")
    sec = {s["key"]: s for s in data["sections"]}
    assert sec["lens"]["ok"] and (d / "layout.png").stat().st_size > 0
    assert not sec["bokeh"]["ok"] and "RuntimeError: boom in the bokeh map" in sec["bokeh"]["errors"][0]
    assert "raise RuntimeError" in sec["bokeh"]["traceback"]
    assert sec["dof"]["errors"] == ["this lens has no depth of field -- try another"]
    assert data["failed_sections"] == ["bokeh", "dof"]
    page = (d / "index.html").read_text(encoding="utf-8")
    assert 'data-report="failed"' in page and page.count("This section failed") == 2
    assert "boom in the bokeh map" in page and "made before the failure" in page
    assert page.count("Skipped (") == 5


def test_a_failed_comparison_is_named_by_the_sections_that_need_it(tmp_path, monkeypatch):
    import lensrt.analysis.compare.comparison as cmp
    from lensrt.errors import LensrtError

    def fail(*a, **k):
        raise LensrtError("no real ray passes")
    monkeypatch.setattr(cmp, "compare_lens", fail)
    d = tmp_path / "r"
    skip = [a for k in ("lens", "psf", "mtf", "bokeh", "dof") for a in ("--skip", k)]
    assert main(["report", "--out", str(d), "--quality", "draft", "--device", "cpu", "--quiet"] + skip) == 1
    sec = {s["key"]: s for s in _strict_json(d / "report.json")["sections"]}
    assert sec["first_order"]["errors"] == ["real-ray values missing: no real ray passes"]
    assert sec["first_order"]["data"]["first_order"]["efl_mm"] > 0  # the paraxial half is there
    for k in ("aberrations", "image_quality"):
        assert sec[k]["errors"] == ["needs the paraxial-against-real comparison, which failed: no real ray passes"]


def test_bad_input_writes_nothing(tmp_path, capsys):
    d = tmp_path / "r"
    assert main(["report", "no_such_lens", "--out", str(d), "--quiet"]) == 2
    assert main(["report", "--out", str(d), "--f-number", "0.5", "--quiet"]) == 2
    assert "wider than the lens opens" in capsys.readouterr().err
    assert not d.exists()


def test_progress_bar_and_steps():
    from lensrt.views.progress import ProgressBar, StepProgress, bar_line

    class Tty(io.StringIO):
        def isatty(self):
            return True
    assert bar_line("x", 3, 12, 6.0) == "x [######..................] 3/12, 6.0 s, ~18 s left"
    t = Tty()
    bar = ProgressBar("fields", t)
    bar(1, 2)
    bar(2, 2)
    text = t.getvalue()
    assert text.startswith("\rfields [############............] 1/2") and text.endswith("\n")
    plain = io.StringIO()  # not a terminal: no bars, one line per step start and end
    steps = StepProgress(2, plain)
    steps.start("first")(1, 4)
    steps.finish(True)
    steps.start("second")
    steps.finish(False, "what broke")
    lines = plain.getvalue().splitlines()
    assert lines[0] == "[1/2] first ..." and re.fullmatch(r"\[1/2\] first: ok, \d+\.\d s", lines[1])
    assert re.fullmatch(r"\[2/2\] second: FAILED after \d+\.\d s \(what broke\)", lines[3])


def test_html_table_escapes_and_aligns():
    from lensrt.report.html import html_table
    from lensrt.io.table import Table
    h = html_table(Table([["<b>", 1.5, "0.98 +- 0.01", "over-corrected"]], ["a", "b", "c", "d"], digits=2,
                         title="T & U"))
    assert "&lt;b&gt;" in h and "<b>" not in h and "T &amp; U" in h
    cells = re.findall(r'<td class="(t?)">([^<]*)</td>', h)
    assert cells == [("t", "&lt;b&gt;"), ("", "1.50"), ("", "0.98 \u00b1 0.01"), ("t", "over-corrected")]


# ---- headless Chromium -------------------------------------------------------------------------

@pytest.fixture(scope="session")
def chromium():
    """Path of Debian's chromium; installed with apt-get when missing and we are root (CI)."""
    if os.path.exists(CHROMIUM):
        return CHROMIUM
    if not (hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("apt-get")):
        pytest.skip("chromium is not installed and cannot be installed here (needs root and apt-get): "
                    "apt-get install chromium")
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    try:
        for cmd in (["apt-get", "update", "-qq"], ["apt-get", "install", "-y", "-qq", "chromium"]):
            subprocess.run(cmd, check=True, env=env, timeout=900, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    except (subprocess.SubprocessError, OSError) as err:
        pytest.skip(f"could not install chromium with apt-get: {err}")
    if not os.path.exists(CHROMIUM):
        pytest.skip("apt-get installed no /usr/bin/chromium")
    return CHROMIUM


def _chromium(binary: str, profile: Path, *args: str) -> subprocess.CompletedProcess:
    cmd = [binary, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync", "--hide-scrollbars",
           f"--user-data-dir={profile}", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=180)


def _image_state(binary: str, page: Path, profile: Path) -> tuple[str, str, int]:
    """(data-images, data-broken-images, number of img marked broken) after the page has loaded."""
    r = _chromium(binary, profile, "--virtual-time-budget=5000", "--dump-dom", page.as_uri())
    body = re.search(r"<body([^>]*)>", r.stdout)
    assert body, f"no DOM from chromium: {r.stderr[-2000:]}"
    attrs = dict(re.findall(r'([\w-]+)="([^"]*)"', body.group(1)))
    return attrs.get("data-images", ""), attrs.get("data-broken-images", ""), r.stdout.count('data-broken="1"')


@pytest.mark.parametrize("name", list(LENSES))
def test_chromium_renders_every_image(reports, chromium, name, tmp_path):
    d, _ = reports[name]
    state = _image_state(chromium, d / "index.html", tmp_path / "profile")
    assert state == ("ok", "0", 0)
    shot = tmp_path / "shot.png"
    r = _chromium(chromium, tmp_path / "profile2", "--virtual-time-budget=5000", f"--screenshot={shot}",
                  "--window-size=1400,5000", (d / "index.html").as_uri())
    assert shot.exists(), r.stderr[-2000:]
    from PIL import Image
    with Image.open(shot) as im:
        assert im.size == (1400, 5000)
        a = np.asarray(im.convert("L"), dtype=np.float64)
    assert a[:1500].std() > 10.0  # text, tables and figures, not a blank page


def test_chromium_check_catches_a_broken_image(reports, chromium, tmp_path):
    """The page's own check marks an image whose file is gone (so the test above can fail)."""
    src, _ = reports["dgauss_50mm_f2"]
    d = tmp_path / "copy"
    shutil.copytree(src, d)
    (d / "spots.png").unlink()
    images, broken, marked = _image_state(chromium, d / "index.html", tmp_path / "profile")
    assert (images, broken, marked) == ("broken", "1", 1)
