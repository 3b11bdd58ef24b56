"""Native TOML format: reading, writing, round trips and clear errors."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from lensrt.errors import PrescriptionError
from lensrt.prescription.formats import read_lens
from lensrt.prescription.formats.native import dumps_native, loads_native

MINIMAL = """
[aperture]
type = "epd"
value = 10.0
[fields]
y = [0.0, 5.0]
[wavelengths]
nm = [587.6]
[[surface]]
radius_mm = 50.0
thickness_mm = 5.0
material = "N-BK7"
semi_diameter_mm = 8.0
stop = true
[[surface]]
radius_mm = -50.0
thickness_mm = 47.0
semi_diameter_mm = 8.0
"""


def test_minimal_lens() -> None:
    lens = loads_native(MINIMAL)
    assert lens.n_surfaces == 2 and lens.stop_index == 0
    assert lens.surfaces[0].curvature_per_mm == pytest.approx(0.02)
    assert lens.fields.y[1] == pytest.approx(math.radians(5.0))
    assert math.isinf(lens.object_distance_mm)


def test_round_trip_is_identical(library_dir: Path) -> None:
    for path in sorted(library_dir.glob("*.toml")):
        lens = read_lens(path)
        again = loads_native(dumps_native(lens))
        assert again == lens, path.name


@pytest.mark.parametrize("edit,needle", [
    (("thickness_mm = 5.0", "thicknes_mm = 5.0"), "unknown key"),
    (("stop = true", "stop = false"), "no aperture stop"),
    (("radius_mm = -50.0", "radius_mm = -50.0\nstop = true"), "2 aperture stops"),
    (("value = 10.0", "value = nan"), "aperture"),
    (("thickness_mm = 47.0", "thickness_mm = inf"), "thickness"),
    (("material = \"N-BK7\"", "material = \"N-BK77\""), "no catalog"),
    (("semi_diameter_mm = 8.0\nstop", "semi_diameter_mm = 60.0\nstop"), "exceeds"),
    (("type = \"epd\"\nvalue = 10.0", "type = \"image_fno\"\nvalue = 0.3"), "below 0.5"),
    (("[[surface]]\nradius_mm = 50.0", "[[surface]\nradius_mm = 50.0"), "not valid TOML"),
])
def test_errors_name_the_problem_and_line(edit: tuple[str, str], needle: str) -> None:
    text = MINIMAL.replace(*edit)
    assert text != MINIMAL
    with pytest.raises(PrescriptionError) as err:
        loads_native(text, path="x.toml")
    msg = str(err.value)
    assert needle in msg
    assert msg.startswith("x.toml")


def test_surface_error_carries_its_line() -> None:
    text = MINIMAL.replace("material = \"N-BK7\"", "material = \"N-BK77\"")
    with pytest.raises(PrescriptionError) as err:
        loads_native(text, path="x.toml")
    assert err.value.line == text.splitlines().index("[[surface]]") + 1
