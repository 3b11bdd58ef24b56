"""The same lens from .seq, a hand-written .zmx and native TOML is the same model; imports round-trip exactly.

"Same" covers everything that describes the optics: surfaces (curvature, thickness,
material, semi-diameter, conic, aspheres, stop, label), aperture, fields, wavelengths,
object distance and medium, iris, and the vignetting factors kept in ``notes``. The
name, the source citation and format-specific notes (a Zemax NOTE, CODE V's image
defocus remark, stated values in the library file) legitimately differ.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from lensrt.prescription.formats import read_lens
from lensrt.prescription.formats.native import dumps_native, loads_native
from lensrt.prescription.model import Lens

OPTICAL = ("surfaces", "aperture", "fields", "wavelengths", "object_distance_mm", "object_material", "iris")
REFERENCE_FILES = ["ag_dblgauss.seq", "ag_dblgauss_handwritten.zmx", "cooke_triplet.zmx", "dgauss.50mm.dat",
                   "dgauss.dat", "wide.22mm.dat", "fisheye.10mm.dat", "telephoto.250mm.dat"]


def optical_model(lens: Lens) -> tuple:
    vignetting = tuple((k, v) for k, v in lens.notes if k.startswith("vignetting_"))
    return tuple(getattr(lens, f) for f in OPTICAL) + (vignetting,)


def test_seq_zmx_and_toml_give_the_same_model(data_dir: Path, library_dir: Path) -> None:
    seq = read_lens(data_dir / "ag_dblgauss.seq")
    zmx = read_lens(data_dir / "ag_dblgauss_handwritten.zmx")
    toml = read_lens(library_dir / "codev_dblgauss_100mm_f2.toml")
    assert optical_model(zmx) == optical_model(seq)
    assert optical_model(toml) == optical_model(seq)
    # field by field, so a failure names what differs
    for a, b in zip(seq.surfaces, zmx.surfaces):
        assert (a.curvature_per_mm, a.thickness_mm, a.material, a.is_stop) == \
            (b.curvature_per_mm, b.thickness_mm, b.material, b.is_stop)
    assert seq.meta["vignetting_vuy"] == zmx.meta["vignetting_vuy"] == toml.meta["vignetting_vuy"]
    # what legitimately differs
    assert seq.name != toml.name and "CODE V" in toml.source and zmx.source.startswith("Zemax file")


@pytest.mark.parametrize("name", REFERENCE_FILES)
def test_reference_import_round_trips(data_dir: Path, name: str) -> None:
    lens = read_lens(data_dir / name)
    again = loads_native(dumps_native(lens))
    assert again == lens  # every field, notes and name included


def test_library_round_trips(library_dir: Path) -> None:
    files = sorted(library_dir.glob("*.toml"))
    assert len(files) >= 10
    for path in files:
        lens = read_lens(path)
        assert loads_native(dumps_native(lens)) == lens, path.name


def test_round_trip_through_a_file_and_the_cli(data_dir: Path, tmp_path: Path) -> None:
    from lensrt.cli import main
    for name in ("ag_dblgauss.seq", "cooke_triplet.zmx", "dgauss.dat"):
        out = tmp_path / (Path(name).stem + ".toml")
        assert main(["lens", "convert", str(data_dir / name), str(out)]) == 0
        assert read_lens(out) == read_lens(data_dir / name)  # path is not part of equality
