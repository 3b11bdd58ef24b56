"""pbrt .dat reader: both thickness conventions, the sign convention, the stated defaults."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from lensrt.errors import PrescriptionError
from lensrt.prescription.formats import read_lens
from lensrt.prescription.formats.pbrt import loads_pbrt
from lensrt.prescription.materials import ConstantIndex

# /work/shared/lenses/README.md: paraxial values from the tables (constant index, infinity focus)
TABLE = {
    "dgauss.50mm.dat": (50.358, 36.106, 2.03),
    "wide.22mm.dat": (22.023, 14.318, 2.68),
    "fisheye.10mm.dat": (9.991, 23.161, 3.95),
    "telephoto.250mm.dat": (249.567, 105.070, 5.42),
}


def _ynu_efl_bfl(rows: list[tuple[float, float, float]]) -> tuple[float, float]:
    """Independent oracle: a ynu trace of (radius, thickness to next, index after) rows,
    textbook signs (R > 0 centre toward the image): n'u' = nu - y (n' - n)/R, y += t u'."""
    y, u, n = 1.0, 0.0, 1.0
    for k, (r, t, n2) in enumerate(rows):
        c = 0.0 if r == 0 else 1.0 / r
        u = (n * u - y * c * (n2 - n)) / n2
        n = n2
        if k < len(rows) - 1:
            y += t * u
    return -1.0 / u, -y / u


@pytest.mark.parametrize("name", sorted(TABLE))
def test_against_the_reference_table(data_dir: Path, name: str) -> None:
    from lensrt.loading import load_lens
    from lensrt.paraxial import first_order
    lens = load_lens(data_dir / name)
    fo = first_order(lens)
    efl, bfl, fno = TABLE[name]
    assert fo.efl_mm == pytest.approx(efl, abs=6e-4)
    assert fo.bfl_mm == pytest.approx(bfl, abs=6e-4)
    assert fo.f_number == pytest.approx(fno, abs=6e-3)
    # the image surface sits at the paraxial focus (the table's last distance is 0)
    assert lens.surfaces[-1].thickness_mm == pytest.approx(fo.bfl_mm, rel=1e-12)


@pytest.mark.parametrize("name", sorted(TABLE))
def test_sign_convention_with_an_independent_trace(data_dir: Path, name: str) -> None:
    rows = []
    for line in (data_dir / name).read_text().splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            r, t, n, _ = (float(v) for v in line.split())
            rows.append((r, t, 1.0 if n == 0 else n))
    efl, bfl = _ynu_efl_bfl(rows)
    lens = read_lens(data_dir / name)
    assert efl == pytest.approx(TABLE[name][0], abs=6e-4)
    assert lens.surfaces[-1].thickness_mm == pytest.approx(bfl, rel=1e-12)


def test_previous_convention_is_detected_and_equals_next_at_2x(data_dir: Path) -> None:
    big = read_lens(data_dir / "dgauss.dat")
    small = read_lens(data_dir / "dgauss.50mm.dat")
    assert big.meta["pbrt_thickness"] == "previous (detected)"
    assert small.meta["pbrt_thickness"] == "next (detected)"  # its header also says 'axpos'
    assert big.n_surfaces == small.n_surfaces
    for a, b in zip(big.surfaces, small.surfaces):
        assert a.thickness_mm == pytest.approx(2 * b.thickness_mm, rel=1e-3, abs=1e-9)
        assert a.curvature_per_mm == pytest.approx(0.5 * b.curvature_per_mm, rel=1e-3)
        assert a.semi_diameter_mm == pytest.approx(2 * b.semi_diameter_mm, rel=1e-12)
        assert a.is_stop == b.is_stop


def test_explicit_convention_overrides_the_header(data_dir: Path) -> None:
    text = (data_dir / "dgauss.dat").read_text()
    lens = loads_pbrt(text, "dgauss.dat", thickness="previous")
    assert lens == read_lens(data_dir / "dgauss.dat").replace(notes=lens.notes)
    assert lens.meta["pbrt_thickness"] == "previous (option)"
    with pytest.raises(PrescriptionError, match="first row's axial distance"):
        loads_pbrt((data_dir / "dgauss.50mm.dat").read_text(), "x.dat", thickness="previous")
    nxt = read_lens(data_dir / "dgauss.dat", pbrt_thickness="next")  # through read_lens's option names
    assert nxt.surfaces[0].thickness_mm == 0.0


def test_defaults_are_stated(data_dir: Path) -> None:
    lens = read_lens(data_dir / "fisheye.10mm.dat")
    assert math.isinf(lens.object_distance_mm)
    assert lens.aperture.kind == "float_by_stop"
    assert lens.wavelengths.nm == (486.1, 587.6, 656.3) and lens.wavelengths.primary_nm == 587.6
    assert all(isinstance(s.material, ConstantIndex) or s.material.is_air for s in lens.surfaces)
    assert lens.stop_index == 6 and lens.surfaces[6].semi_diameter_mm == 3.04
    notes = lens.meta["pbrt_defaults"]
    for words in ("object at infinity", "floats by the stop", "constant indices", "486.1, 587.6, 656.3", "fields"):
        assert words in notes
    assert lens.name == "Muller 16mm/f4 155.9FOV fisheye lens"
    wide = read_lens(data_dir / "fisheye.10mm.dat", pbrt_field_deg=77.95)
    assert math.degrees(wide.fields.y[-1]) == pytest.approx(77.95)


def test_default_field_is_the_chief_ray_limit(data_dir: Path) -> None:
    """At the default field the paraxial chief ray just reaches the tightest clear aperture."""
    from lensrt.paraxial import paraxial_system, pupils
    from lensrt.paraxial.first_order import chief_ray
    lens = read_lens(data_dir / "dgauss.50mm.dat")
    sysm = paraxial_system(lens)
    ray = chief_ray(lens, sysm, lens.fields.y[-1], math.inf, pupils(sysm).entrance_z_mm, 1.0)
    ratio = max(abs(y) / s.semi_diameter_mm for y, s in zip(ray.y, lens.surfaces))
    assert ratio == pytest.approx(1.0, abs=2e-4)  # the angle is rounded to 0.001 deg


@pytest.mark.parametrize("text,needle", [
    ("10 2 1.5\n-10 40 1 10\n", "3 columns"),
    ("10 2 1.5 10\n0 1 0 8\n0 40 1 10\n", "2 aperture stops"),
    ("10 2 1.5 10\n-10 40 1 10\n", "no aperture stop"),
    ("10 2 0 10\n0 1 0 8\n-10 40 1 10\n", "index 0"),
    ("10 2 1.5 -10\n0 1 0 8\n-10 40 1 10\n", "diameter"),
    ("10 2 1.5 30\n0 1 0 8\n-10 40 1 10\n", "exceeds"),
    ("10 nan 1.5 10\n0 1 0 8\n-10 40 1 10\n", "thickness is 'nan'"),
    ("10 2 9.5 10\n0 1 0 8\n-10 40 1 10\n", "not physical"),
    ("-10 2 1.5 10\n0 1 0 8\n10 0 1 10\n", "paraxial image"),
    ("# only a comment\n", "no lens rows"),
])
def test_bad_tables(text: str, needle: str) -> None:
    with pytest.raises(PrescriptionError) as err:
        loads_pbrt(text, "bad.dat")
    assert needle in str(err.value) and str(err.value).startswith("bad.dat")


def test_iset_focal_length_header() -> None:
    """ISET isetlens' variant: '# Focal length' then one number before the rows; read, kept as a note, and the
    lens equals the same table without the header. A lone number anywhere else is still an error."""
    rows = "# radius axpos N aperture\n20 3 1.5 10\n0 2 0 8\n-20 0 1 10\n"
    lens = loads_pbrt("# Name: x\n# Focal length\n20.000\n\n" + rows, "iset.dat")
    plain = loads_pbrt(rows, "plain.dat")
    assert [s.curvature_per_mm for s in lens.surfaces] == [s.curvature_per_mm for s in plain.surfaces]
    assert [s.thickness_mm for s in lens.surfaces] == [s.thickness_mm for s in plain.surfaces]
    assert dict(lens.notes)["stated_focal_length_mm"].startswith("20 (ISET")
    for bad in ("20.000\n" + rows, "# Focal length\n20\n" + rows + "50\n"):
        with pytest.raises(PrescriptionError, match="1 columns"):
            loads_pbrt(bad, "bad.dat")
