"""Each colour concept is defined once, in lensrt/colour (issue 24: "one home per colour concept").

AST checks over the package: colour-science's colorimetry tables are read by one module each, all
inside lensrt/colour; no function outside it is named like an sRGB curve/matrix, a CMF or V(lambda)
loader, a Planck law or an illuminant parser; no sRGB constants (matrix entries, transfer-curve
breakpoints) are typed in anywhere; and no code outside lensrt/colour tells illuminants apart by
comparing strings ("D65", "blackbody:...", "CIE ...") -- spectra travel as Illuminant objects.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[2] / "lensrt"
COLOUR = PKG / "colour"

#: colour-science table / function -> the one module of lensrt/colour that may read it
TABLES = {
    "MSDS_CMFS": "cmfs.py", "SDS_LEFS": "cmfs.py",
    "SDS_ILLUMINANTS": "illuminants.py", "sd_blackbody": "illuminants.py", "planck_law": "illuminants.py",
    "sd_CIE_illuminant_D_series": "illuminants.py", "CCT_to_xy_CIE_D": "illuminants.py",
    "CCS_ILLUMINANTS": "rgb.py", "RGB_COLOURSPACES": "rgb.py", "eotf_sRGB": "rgb.py", "eotf_inverse_sRGB": "rgb.py",
    "cctf_encoding": "rgb.py", "cctf_decoding": "rgb.py", "XYZ_to_Lab": "rgb.py",
    "SDS_COLOURCHECKERS": "charts.py", "MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019": "reflectance.py",
}
#: function names that would be a second copy of a colour concept
COPY_NAMES = re.compile(r"(?i)(srgb_(en|de)code|eotf|cctf|^_?xyz_to_(linear_)?srgb$|srgb_to_xyz|srgb_matri|cmfs|"
                        r"photopic|"
                        r"planck|blackbody|illuminant_spd|spd_values|parse_illuminant|^_?illuminant$|"
                        r"colorchecker_(reflectances|names)|mallett|as_cct)")
#: numbers of the sRGB standard (IEC 61966-2-1 matrix entries and transfer-curve constants)
SRGB_NUMBERS = {12.92, 0.0031308, 0.04045, 1.055, 0.055, 3.2406, 3.2404542, -1.5372, -1.5371385, 0.4124,
                0.4124564, 0.3576, 0.3575761, 0.2126, 0.2126729, 0.7152, 0.7151522}
#: string constants that, compared against, would mean an illuminant is told apart by its name
NAME_TESTS = re.compile(r"(?i)^(blackbody|bb|planck|daylight|lines)(:.*)?$|^d65$|^fl?([1-9]|1[0-2])$|^cie$|^e$")


def _modules():
    for path in sorted(PKG.rglob("*.py")):
        yield path, ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


def _docstring_nodes(tree: ast.AST) -> set[int]:
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                out.add(id(first.value))
    return out


def test_each_colour_science_table_is_read_by_one_module_in_lensrt_colour():
    readers: dict[str, set[str]] = {}
    for path, tree in _modules():
        for node in ast.walk(tree):
            name = node.attr if isinstance(node, ast.Attribute) else (
                node.name if isinstance(node, ast.alias) else None)
            if isinstance(node, ast.alias):
                name = node.name.rsplit(".", 1)[-1]
            if name in TABLES:
                readers.setdefault(name, set()).add(str(path.relative_to(PKG)))
    wrong = {k: sorted(v) for k, v in readers.items() if v != {f"colour/{TABLES[k]}"}}
    assert not wrong, f"colour-science tables read outside their one home: {wrong}"
    assert "MSDS_CMFS" in readers and "SDS_ILLUMINANTS" in readers and "RGB_COLOURSPACES" in readers


def test_no_second_copy_of_a_colour_function_outside_lensrt_colour():
    copies = []
    for path, tree in _modules():
        if COLOUR in path.parents:
            continue
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and COPY_NAMES.search(node.name):
                copies.append(f"{path.relative_to(PKG)}:{node.lineno} {node.name}")
    assert not copies, "colour concepts defined outside lensrt/colour: " + ", ".join(copies)


def test_no_srgb_constants_typed_in():
    found = []
    for path, tree in _modules():
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, float) and node.value in SRGB_NUMBERS:
                found.append(f"{path.relative_to(PKG)}:{node.lineno} {node.value}")
    assert not found, "sRGB numbers typed in (take them from colour-science via lensrt.colour): " + ", ".join(found)


def _compared_strings(tree: ast.AST):
    """String constants that code compares against (==, in, startswith, endswith, partition, split)."""
    for node in ast.walk(tree):
        consts = []
        if isinstance(node, ast.Compare):
            consts = [node.left, *node.comparators]
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and \
                node.func.attr in ("startswith", "endswith", "partition"):
            consts = list(node.args)
        for c in consts:
            items = c.elts if isinstance(c, (ast.Tuple, ast.List, ast.Set)) else [c]
            for item in items:
                if isinstance(item, ast.Constant) and isinstance(item.value, str):
                    yield item


def test_illuminants_are_not_told_apart_by_name_outside_lensrt_colour():
    found = []
    for path, tree in _modules():
        if COLOUR in path.parents:
            continue
        for c in _compared_strings(tree):
            if NAME_TESTS.search(c.value.strip()):
                found.append(f"{path.relative_to(PKG)}:{c.lineno} {c.value!r}")
    assert not found, "illuminant names parsed outside lensrt.colour: " + ", ".join(found)


def test_lensrt_colour_imports_only_the_bottom_floor():
    allowed = {"errors", "units", "core"}
    bad = []
    for path in sorted(COLOUR.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level >= 2:
                top = (node.module or "").split(".")[0]
                if top not in allowed:
                    bad.append(f"{path.name}: from {'.' * node.level}{node.module}")
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("lensrt"):
                bad.append(f"{path.name}: from {node.module}")
            elif isinstance(node, ast.Import) and any(a.name.startswith("lensrt") for a in node.names):
                bad.append(f"{path.name}: import lensrt...")
    assert not bad, bad


@pytest.mark.parametrize("probe", [
    "def srgb_encode(x):\n    return x\n",
    "M = [[3.2406, -1.5372, -0.4986]]\n",
    "def f(s):\n    return s.startswith('blackbody:')\n",
    "import colour\nx = colour.MSDS_CMFS\n",
])
def test_the_checks_see_a_planted_copy(probe, tmp_path):
    # the guards are not vacuous: a planted copy in a module outside lensrt/colour is caught
    global PKG, COLOUR
    fake = tmp_path / "lensrt"
    (fake / "colour").mkdir(parents=True)
    (fake / "colour" / "__init__.py").write_text("")
    (fake / "isp").mkdir()
    (fake / "isp" / "tone.py").write_text(probe)
    old = PKG, COLOUR
    PKG, COLOUR = fake, fake / "colour"
    try:
        checks = [test_no_second_copy_of_a_colour_function_outside_lensrt_colour, test_no_srgb_constants_typed_in,
                  test_illuminants_are_not_told_apart_by_name_outside_lensrt_colour]
        failed = 0
        for check in checks:
            try:
                check()
            except AssertionError:
                failed += 1
        if "MSDS_CMFS" in probe:
            with pytest.raises(AssertionError):
                test_each_colour_science_table_is_read_by_one_module_in_lensrt_colour()
        else:
            assert failed >= 1
    finally:
        PKG, COLOUR = old
