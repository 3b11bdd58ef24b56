"""First-order data of the CODE V double Gauss against its listing (core check; see test_paraxial.py)."""
from __future__ import annotations

import pytest

from lensrt import load_lens
from lensrt.paraxial import first_order


def test_codev_double_gauss_first_order(library_dir) -> None:
    fo = first_order(load_lens(library_dir / "codev_dblgauss_100mm_f2.toml"))
    assert fo.efl_mm == pytest.approx(100.0038, abs=5e-5)
    assert fo.bfl_mm == pytest.approx(61.4875, abs=5e-5)
    assert fo.ffl_mm == pytest.approx(-29.3208, abs=5e-5)
    assert fo.f_number == pytest.approx(2.0001, abs=5e-5)
    assert fo.entrance_pupil_z_mm == pytest.approx(57.9120, abs=5e-5)
    assert fo.exit_pupil_diameter_mm == pytest.approx(57.3201, abs=5e-5)
    assert fo.exit_pupil_z_mm - 77.9674 == pytest.approx(-53.1569, abs=1e-4)
    assert fo.paraxial_image_height_mm == pytest.approx(24.9337, abs=5e-5)
