"""Property-based bad input (Hypothesis): generated lens files, scene files and argument sets, hostile ones included.

Every example either succeeds with a sane result or ends in ONE error line that names the file or
the argument -- never an internal error (exit status 3, a traceback), never ``nan`` in a printed or
JSON result, never a hang (a SIGALRM watchdog per example) and never a large allocation (the
tracemalloc peak of the example, which numpy reports to, stays under :data:`MEMORY_CAP`).

Profiles (tests/conftest.py): ``ci`` by default (a dozen examples per property, derandomised; the
whole file runs in well under a minute on 2 cores), ``HYPOTHESIS_PROFILE=long`` for local runs.
CLI cases run in this process through :func:`lensrt.cli.main`.
"""
from __future__ import annotations

import contextlib
import io
import math
import re
import signal
import tempfile
import tracemalloc
import warnings
from pathlib import Path

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import example, given, strategies as st  # noqa: E402

from lensrt.cli import main  # noqa: E402
from lensrt.errors import LensrtError  # noqa: E402
from lensrt.loading import load_lens  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
#: a generated example may not hold more than this much traced memory at its peak
MEMORY_CAP = 512 << 20
#: an example that takes longer than this (s) counts as a hang
WATCHDOG_S = 60
NAN = re.compile(r"(?<![A-Za-z_])nan(?![A-Za-z_])", re.IGNORECASE)


class Hang(Exception):
    pass


@pytest.fixture(scope="module", autouse=True)
def warm_up() -> None:
    """Load every glass catalog and the library once, outside the per-example watchdog and tracemalloc
    (the first catalog import takes seconds, and an alarm inside an import would leave it half done)."""
    from lensrt.prescription.materials import find_glass
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        load_lens("dgauss_50mm_f2")
        with contextlib.redirect_stdout(io.StringIO()):
            main(["sensor", "expose", "--flat", "100", "--size", "16x16"])  # colour-science and the ISP
        with contextlib.suppress(LensrtError):
            find_glass("NOSUCH")


@contextlib.contextmanager
def bounded():
    """A SIGALRM watchdog and a tracemalloc peak check around one example."""
    def alarm(signum, frame):  # noqa: ANN001
        raise Hang(f"no answer within {WATCHDOG_S} s")
    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(WATCHDOG_S)
    tracemalloc.start()
    try:
        yield
        peak = tracemalloc.get_traced_memory()[1]
        assert peak < MEMORY_CAP, f"peak traced memory {peak / 2**20:.0f} MiB"
    finally:
        tracemalloc.stop()
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    """(exit status, stdout, stderr) of ``lensrt argv`` in this process, bounded in time and memory."""
    out, err = io.StringIO(), io.StringIO()
    with bounded(), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            rc = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse
            rc = exc.code
    return int(rc or 0), out.getvalue(), err.getvalue()


def check_outcome(argv: list[str], rc: int, out: str, err: str, names: list[str]) -> None:
    """Success without nan, or exit 2 with one error line naming one of ``names`` (file or argument)."""
    assert "Traceback" not in out + err and "internal error" not in err, (argv, err)
    assert rc in (0, 2), (argv, rc, err)
    if rc == 0:
        assert not NAN.search(out), (argv, out[:2000])
        return
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("lensrt: warning:")]
    last = lines[-1]
    if last.startswith("lensrt: error: "):
        assert len(lines) == 1, (argv, err)
    else:  # argparse: usage, then one "lensrt CMD: error: argument --x: ..." line
        assert ": error: " in last, (argv, err)
    assert any(n in last for n in names), (argv, last, names)


# --------------------------------------------------------------------------- lens files

NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-300, 1e300, -1e300, 1e-9, 1e9, 1e-3, 0.7, 1.0, 1.5, 5.0, 50.0, -50.0, -5.0]),
    st.floats(min_value=-200.0, max_value=200.0),
)
POSITIVE = st.one_of(st.floats(min_value=0.5, max_value=100.0), NUMBERS)
GLASSES = st.sampled_from(['"N-BK7"', '"F2"', '{ glass = "N-SK16", catalog = "Schott" }', '"NOSUCH"', '{ index = 0.7 }',
                           '{ index = 1.6 }', '{ index = 0.7, exotic = true }', '{ nd = 1.5, vd = 60 }', '"air"',
                           '{ index = 1e9 }', '{ nd = 0.9, vd = 30 }', '42', '{ glass = "F2", catalog = "Nope" }'])
CATALOG_NAMES = st.lists(st.one_of(st.sampled_from(["Schott", "ohara", "HOYA", "Nope", ""]),
                                   st.text(alphabet="abcXYZ-_ 1", max_size=8)), max_size=3)


def _toml_float(v: float) -> str:
    return "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(float(v)))


@st.composite
def native_lenses(draw) -> str:
    r1, r2 = draw(st.one_of(st.just(50.0), NUMBERS)), draw(st.one_of(st.just(-50.0), NUMBERS))
    t1, t2 = draw(st.one_of(st.just(5.0), NUMBERS)), draw(st.one_of(st.just(47.0), POSITIVE))
    epd = draw(st.one_of(st.just(10.0), POSITIVE))
    weights = draw(st.one_of(st.just([1.0]), st.lists(st.sampled_from([0.0, -1.0, 1.0, 2.0, math.nan]),
                                                       min_size=1, max_size=3)))
    text = ['format = "lensrt-lens"\nversion = 1\n[lens]\nname = "generated"\n[system]\nobject_distance_mm = inf']
    cats = draw(st.none() | CATALOG_NAMES)
    if cats is not None:
        text.append("catalogs = [" + ", ".join('"' + c.replace('"', "") + '"' for c in cats) + "]")
    text.append(f'[aperture]\ntype = "epd"\nvalue = {_toml_float(epd)}')
    text.append(f"[fields]\ntype = \"angle\"\ny = [0.0, {_toml_float(draw(st.sampled_from([5.0, 20.0, 89.0, 200.0])))}]")
    text.append("[wavelengths]\nnm = [" + ", ".join(["550.0"] * len(weights)) + "]\nweights = ["
                + ", ".join(_toml_float(w) for w in weights) + "]")
    for k, (r, t) in enumerate(((r1, t1), (r2, t2))):
        row = [f"[[surface]]\nradius_mm = {_toml_float(r)}\nthickness_mm = {_toml_float(t)}"]
        material = draw(GLASSES) if k == 0 else '"air"'
        row.append(f"material = {material}")
        if draw(st.booleans()):
            row.append(f"semi_diameter_mm = {_toml_float(draw(st.one_of(st.just(8.0), NUMBERS)))}")
        if draw(st.integers(0, 4)) == 0:
            power = draw(st.one_of(st.integers(2, 50), st.integers(0, 10 ** 9)))
            row.append(f"asphere = {{ A{power} = {_toml_float(draw(NUMBERS))} }}")
        if k == 0:
            row.append("stop = true")
        text.append("\n".join(row))
    return "\n".join(text) + "\n"


@st.composite
def zemax_lenses(draw) -> str:
    head = ["VERS 1 0 0", "MODE SEQ", "UNIT MM", f"ENPD {draw(POSITIVE)!r}", "FTYP 0 0 1 1", "YFLN 0",
            f"WAVM 1 0.55 {draw(st.sampled_from(['1', '0', '-1', 'nan']))}", "GCAT SCHOTT", "SURF 0", "  DISZ INFINITY"]
    lines = list(head)
    for n in (1, 2):
        lines.append(f"SURF {n}")
        if n == 1:
            lines.append("  STOP")
        for _ in range(draw(st.integers(1, 5))):
            kw = draw(st.sampled_from(["CURV", "DISZ", "GLAS", "DIAM", "PARM", "TYPE", "CONI"]))
            if kw == "GLAS":
                lines.append("  GLAS " + draw(st.sampled_from(["N-BK7", "NOSUCH 0 0 1.5 60", "", "MIRROR",
                                                               # issue 25: 1980 glasses, tables, grades, prefixes
                                                               "BK7", "B270 0 0 1.5 40", "S-LAL7Q 0 0 1.6516 58.54",
                                                               "S-LAL7Q 0 0 1.9 20", "LF5HT 0 0 1.58148 40.9",
                                                               "LZ_K8", "NICF-A 0 0 1.43387 95.1"])))
            elif kw == "TYPE":
                lines.append("  TYPE " + draw(st.sampled_from(["STANDARD", "EVENASPH", "TOROIDAL", ""])))
            elif kw == "PARM":
                lines.append(f"  PARM {draw(st.one_of(st.integers(-2, 20), st.integers(0, 10 ** 9)))} "
                             f"{draw(NUMBERS)!r}")
            else:
                value = draw(st.one_of(st.none(), NUMBERS))
                lines.append(f"  {kw}" + ("" if value is None else f" {value!r}"))
    lines += ["SURF 3"]
    return "\n".join(lines) + "\n"


@st.composite
def codev_lenses(draw) -> str:
    lines = ["RDM Y", f"EPD {draw(POSITIVE)!r}", "WL 587.6", "YAN 0 " + repr(draw(st.sampled_from([10.0, 89.0]))),
             "SO 0 1e10"]
    glass = draw(st.sampled_from(["NBK7_SCHOTT", "NOSUCH", "", "1.5", "SK19_Schott", "bk7", "FDS30_hoya"]))
    lines.append(f"S {draw(NUMBERS)!r} {draw(NUMBERS)!r} " + glass)
    lines.append("  STO")
    if draw(st.booleans()):
        lines.append(f"  CIR {draw(NUMBERS)!r}")
    lines.append(f"S {draw(NUMBERS)!r} {draw(POSITIVE)!r}")
    lines += ["SI 0 0", "GO"]
    return "\n".join(lines) + "\n"


@st.composite
def pbrt_tables(draw) -> str:
    """pbrt lens tables, with or without ISET's '# Focal length' header line (issue 25)."""
    lines = ["# radius axpos N aperture"]
    if draw(st.booleans()):
        lines[:0] = ["# Focal length", repr(draw(st.one_of(NUMBERS, st.sampled_from([50.0, 0.0, -1.0]))))]
    for _ in range(draw(st.integers(0, 4))):
        lines.append(" ".join(repr(draw(NUMBERS)) for _ in range(draw(st.sampled_from([4, 4, 4, 1, 3])))))
    return "\n".join(lines) + "\n"


def _check_lens_text(text: str, suffix: str) -> None:
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"gen{suffix}"
        path.write_text(text, encoding="utf-8")
        try:
            with bounded(), warnings.catch_warnings():
                warnings.simplefilter("ignore")
                lens = load_lens(path)
        except LensrtError as err:
            msg = str(err)
            assert "\n" not in msg and str(path) in msg, msg
            return
        # a lens that loads is physical: finite numbers, indices >= 1 unless opted in, positive apertures
        for s in lens.surfaces:
            assert math.isfinite(s.curvature_per_mm) and math.isfinite(s.thickness_mm)
            assert s.semi_diameter_mm is not None and s.semi_diameter_mm > 0
            assert len(s.asphere) <= 20
        assert sum(lens.wavelengths.weights) > 0
        idx = lens.indices([550.0])
        assert all(math.isfinite(float(v)) for v in idx.ravel())
        rc, out, err = run_cli(["info", path, "--json"])
        check_outcome(["info", str(path)], rc, out, err, [str(path)])


#: found by the long profile: a 1.5e11 mm thick element loaded, then `info` failed without naming the file
AFOCAL = ('format = "lensrt-lens"\nversion = 1\n[aperture]\ntype = "epd"\nvalue = 10.0\n[fields]\ny = [0.0, 5.0]\n'
          '[wavelengths]\nnm = [550.0]\n[[surface]]\nradius_mm = 50.0\nthickness_mm = 146427852046.0\n'
          'material = "N-BK7"\nsemi_diameter_mm = 8.0\nstop = true\n[[surface]]\nradius_mm = -50.0\n'
          'thickness_mm = 47.0\nsemi_diameter_mm = 8.0\n')


@given(native_lenses())
@example(AFOCAL)
def test_generated_toml_lenses(text: str) -> None:
    _check_lens_text(text, ".toml")


@given(zemax_lenses())
def test_generated_zemax_lenses(text: str) -> None:
    _check_lens_text(text, ".zmx")


@given(codev_lenses())
def test_generated_codev_lenses(text: str) -> None:
    _check_lens_text(text, ".seq")


@given(pbrt_tables())
def test_generated_pbrt_tables(text: str) -> None:
    _check_lens_text(text, ".dat")


# --------------------------------------------------------------------------- scene files

DEFAULT_SCENE = (ROOT / "scenes" / "default.toml").read_text(encoding="utf-8")
SIDES = st.one_of(st.integers(1, 64), st.sampled_from([0, -1, 20000, 65536, 65537, 10 ** 9]))


@st.composite
def scenes(draw) -> tuple[bytes, list[str]]:
    text = DEFAULT_SCENE.replace("pixels = [720, 480]", f"pixels = [{draw(SIDES)}, {draw(SIDES)}]")
    text = text.replace("samples_per_pixel = 256", f"samples_per_pixel = {draw(st.sampled_from([0, 1, 4, -3]))}")
    text = text.replace("seed = 1", f"seed = {draw(st.sampled_from([0, 1, -1, 2 ** 64]))}")
    text = text.replace("focus_distance = 2.0", "focus_distance = "
                        + _toml_float(draw(st.sampled_from([2.0, 1e-9, 0.0, -1.0, math.inf, 1e12]))))
    if draw(st.booleans()):
        text = text.replace("[camera]", f"[camera]\nf_number = {_toml_float(draw(st.sampled_from([0.5, 2.8, 0.0, 16.0])))}")
    if draw(st.booleans()):
        text = text.replace('format = "full-frame"', 'format = "full-frame"\npreset = "'
                            + draw(st.sampled_from(["fullframe_24mp", "nope"])) + '"')
    data = text.encode("utf-8")
    if draw(st.booleans()):
        data = b"\xef\xbb\xbf" + data
    extra = draw(st.sampled_from([[], ["--width", "16"], ["--width", "0"], ["--width", "70000"], ["--seed", "-1"],
                                  ["--max-memory", "1M"], ["--max-memory", "x"]]))
    return data, extra


@given(scenes())
def test_generated_scenes_plan(case: tuple[bytes, list[str]]) -> None:
    data, extra = case
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "scene.toml"
        path.write_bytes(data)
        argv = ["render", str(path), "--plan", *extra]
        rc, out, err = run_cli(argv)
        check_outcome(argv, rc, out, err, [str(path), *[a for a in extra if a.startswith("--")], "render"])
        if rc == 0:
            assert "memory       about" in out


# --------------------------------------------------------------------------- argument sets

HOSTILE_INT = st.sampled_from(["-1", "0", "1", "3", "nan", "1e300", "x", "99999999999999999999", "2"])
HOSTILE_SIZE = st.sampled_from(["16x16", "0x0", "4x4", "100000x100000", "x", "-5x8", "30000x30000"])
HOSTILE_FLOAT = st.sampled_from(["-1", "0", "1e300", "nan", "inf", "0.5", "1", "0.01"])


@st.composite
def sensor_args(draw) -> list[str]:
    sub = draw(st.sampled_from(["characterize", "expose"]))
    argv = ["sensor", sub, "--size", draw(HOSTILE_SIZE), *_seed(draw)]
    if sub == "characterize":
        argv += ["--stack", draw(HOSTILE_INT), "--levels", draw(st.sampled_from(["8", "0", "100000"])),
                 "--exposure-s", draw(HOSTILE_FLOAT)]
    else:
        argv += ["--flat", "100", "--exposure-s", draw(HOSTILE_FLOAT), "--frames", draw(HOSTILE_INT)]
    if draw(st.booleans()):
        argv += ["--max-memory", draw(st.sampled_from(["1M", "0", "abc", "64G"]))]
    return argv


@st.composite
def bokeh_args(draw) -> list[str]:
    argv = ["bokeh", "--rays", "1e4", "--batches", "8", "--no-files", *_seed(draw)]
    if draw(st.booleans()):
        argv += ["--f-number", draw(HOSTILE_FLOAT)]
    if draw(st.booleans()):
        argv += ["--name", draw(st.sampled_from(["ok", "../../x", "/etc/x", "", "a b", ".."]))]
    if draw(st.booleans()):
        argv += ["--map", draw(st.sampled_from(["10000x10000", "0x3", "x"])),
                 "--pixels", draw(st.sampled_from(["40000x26667", "0x0", "64x64"]))]
    if draw(st.booleans()):
        argv += ["--max-rays", draw(st.sampled_from(["1", "1e5"])), "--rays", draw(st.sampled_from(["1e15", "1e4"]))]
    return argv


@st.composite
def psf_args(draw) -> list[str]:
    argv = ["psf", "--field", "0", "--batches", "8", "--rays", draw(st.sampled_from(["1e4", "1e15", "0", "nan"])),
            "--pixels", draw(st.sampled_from(["16", "0", "-3", "100000"])), *_seed(draw)]
    if draw(st.booleans()):
        argv += ["--method", "diffraction", "--pupil-samples", draw(st.sampled_from(["0", "100000", "-1"]))]
    return argv


@st.composite
def sweep_args(draw) -> list[str]:
    argv = ["sweep", "--format", "json"]
    argv += ["--focus-distance-mm", draw(st.sampled_from(["100:1e9:1000000", "500,inf", "0", "nan", "1:2:1e300",
                                                          "1000:2000:3", "a:b:c"]))]
    if draw(st.booleans()):
        argv += ["--f-number", draw(st.sampled_from(["0.5", "2.8,4", "0", "-1", "nan"]))]
    if draw(st.booleans()):
        argv += ["--max-rows", draw(HOSTILE_INT)]
    return argv


def _names(argv: list[str]) -> list[str]:
    return [a for a in argv if a.startswith("--")]


def _seed(draw) -> list[str]:
    return ["--seed", draw(HOSTILE_INT)] if draw(st.integers(0, 3)) == 0 else []


@given(st.one_of(sensor_args(), bokeh_args(), psf_args(), sweep_args()))
@example(["bokeh", "--rays", "1e4", "--batches", "8", "--no-files", "--f-number", "1e300"])  # found by the long profile
def test_generated_argument_sets(argv: list[str]) -> None:
    rc, out, err = run_cli(argv)
    check_outcome(argv, rc, out, err, _names(argv))
