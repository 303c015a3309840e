"""The fabric library (couture/assets/fabrics/library.toml): every entry loads,
passes the design limits, gives every number a source, and the fabrics are
ordered as the literature orders them."""

from __future__ import annotations

import math

import pytest

from couture import fabrics
from couture.fabrics import FabricLibraryError, load
from couture.pattern.limits import check_fabric

DESIGNER_NAMES = (
    "cotton_shirting",
    "poplin",
    "denim",
    "linen",
    "wool_suiting",
    "silk_charmeuse",
    "chiffon",
    "satin",
    "jersey",
    "rib_knit",
    "fleece",
    "canvas",
)


def test_the_library_has_the_fabrics_designers_name():
    assert set(DESIGNER_NAMES) <= set(fabrics.names())
    assert len(fabrics.names()) >= 12


@pytest.mark.parametrize("name", DESIGNER_NAMES)
def test_every_entry_is_complete_sourced_and_in_range(name):
    e = fabrics.entry(name)
    f = fabrics.get(name)
    assert f.name == name
    check_fabric(f)  # raises on a value outside couture.pattern.limits
    for field in fabrics.NUMBERS:
        assert getattr(f, field) is not None, field
        src = e.sources[field]
        assert src.split(":")[0] in ("measured", "estimate", "estimate from measured", "isotropic fallback"), src
    # the isotropic fallbacks are the geometric means the file says they are
    assert f.stretch_stiffness == pytest.approx(math.sqrt(f.warp_stiffness * f.weft_stiffness), rel=0.01)
    assert f.bend_stiffness == pytest.approx(math.sqrt(f.bend_warp * f.bend_weft), rel=0.01)
    assert f.friction_kinetic <= f.friction_static
    assert min(f.bend_warp, f.bend_weft) <= f.bend_bias <= max(f.bend_warp, f.bend_weft)
    assert 0.0 < e.valid_strain <= (0.2 if e.kind == "knit" else 0.05)


def test_get_returns_a_fresh_copy():
    a = fabrics.get("denim")
    b = fabrics.get("denim")
    assert a == b and a is not b


def test_unknown_fabric_names_the_library():
    with pytest.raises(ValueError, match="unknown fabric 'tweed'.*denim"):
        fabrics.get("tweed")


def test_ordering_matches_the_literature():
    """Bending: denim and canvas far stiffer than chiffon and charmeuse (Peirce
    bending lengths 3-5 cm against 1 cm); knits far more extensible than
    wovens; chiffon the lightest, canvas and denim the heaviest."""
    g = fabrics.get
    for stiff in ("denim", "canvas"):
        for soft in ("chiffon", "silk_charmeuse", "jersey"):
            assert g(stiff).bend_stiffness > 10 * g(soft).bend_stiffness, (stiff, soft)
            assert g(stiff).stretch_stiffness > g(soft).stretch_stiffness
    assert g("chiffon").bend_stiffness < g("silk_charmeuse").bend_stiffness < g("cotton_shirting").bend_stiffness
    for knit in ("jersey", "rib_knit", "fleece"):
        assert fabrics.entry(knit).kind == "knit"
        for woven in ("cotton_shirting", "denim", "linen", "wool_suiting"):
            assert g(knit).weft_stiffness < g(woven).weft_stiffness / 3
    assert g("chiffon").area_density == min(g(n).area_density for n in fabrics.names())
    # wovens: soft on the bias (the bias modulus from the orthotropic compliance)
    for n in ("cotton_shirting", "denim", "wool_suiting"):
        f = g(n)
        e45 = 1 / (
            0.25
            * (
                1 / f.warp_stiffness
                + 1 / f.weft_stiffness
                + 1 / f.shear_stiffness
                - 2 * f.poisson_ratio / f.warp_stiffness
            )
        )
        assert e45 < 0.5 * min(f.warp_stiffness, f.weft_stiffness)


def test_measured_rows_convert_as_their_sources_say():
    """The FAST wool suiting: B = W c³ 9.81e-6 µN m, E20 and G = 123 / EB5."""
    f = fabrics.get("wool_suiting")
    assert f.bend_warp == pytest.approx(168 * 15.0**3 * 9.81e-6 * 1e-6, rel=0.005)
    assert f.bend_weft == pytest.approx(168 * 14.5**3 * 9.81e-6 * 1e-6, rel=0.005)
    assert f.warp_stiffness == pytest.approx(19.61 / 0.0187, rel=0.005)
    assert f.shear_stiffness == pytest.approx(123 / 4.7, rel=0.005)
    assert fabrics.entry("wool_suiting").bending_length_warp == pytest.approx(0.015, rel=0.005)
    assert fabrics.get("denim").shear_stiffness == pytest.approx(2.18 * 0.980665 * 180 / math.pi, rel=0.005)


def _write(tmp_path, body: str):
    p = tmp_path / "lib.toml"
    p.write_text(body)
    return p


GOOD = """
[fabric.x]
label = "X"
kind = "woven"
area_density = 0.1
thickness = 0.0003
warp_stiffness = 1000.0
weft_stiffness = 500.0
shear_stiffness = 20.0
poisson_ratio = 0.3
bend_warp = 1e-5
bend_weft = 5e-6
bend_bias = 7e-6
stretch_stiffness = 700.0
bend_stiffness = 7e-6
friction_static = 0.5
friction_kinetic = 0.4
valid_strain = 0.03
[fabric.x.source]
""" + "\n".join(f'{k} = "estimate: test"' for k in (*fabrics.NUMBERS, "valid_strain"))


def test_a_good_file_loads(tmp_path):
    lib = load(_write(tmp_path, GOOD))
    assert list(lib) == ["x"] and lib["x"].fabric.warp_stiffness == 1000.0


@pytest.mark.parametrize(
    "old,new,where",
    [
        ("warp_stiffness = 1000.0", "warp_stiffness = 0.0", r"fabric\.x\.warp_stiffness"),
        ("area_density = 0.1", "area_density = 20.0", r"fabric\.x\.area_density"),
        ("friction_kinetic = 0.4", "friction_kinetic = 0.9", r"fabric\.x\.friction_kinetic"),
        ("bend_bias = 7e-6\n", "", r"fabric\.x\.bend_bias: missing"),
        ('bend_weft = "estimate: test"', 'bend_weft = ""', r"fabric\.x\.source\.bend_weft"),
        ('kind = "woven"', 'kind = "felt"', r"fabric\.x\.kind"),
        ("valid_strain = 0.03", 'valid_strain = "small"', r"fabric\.x\.valid_strain"),
        ("label = ", "colour = 1\nlabel = ", r"fabric\.x\.colour: unknown field"),
    ],
)
def test_a_bad_entry_names_file_fabric_and_field(tmp_path, old, new, where):
    assert old in GOOD
    p = _write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(FabricLibraryError, match=where) as e:
        load(p)
    assert str(p) in str(e.value)


def test_a_file_that_is_not_toml_is_named(tmp_path):
    p = _write(tmp_path, "[fabric.x\n")
    with pytest.raises(FabricLibraryError, match="cannot be read as TOML"):
        load(p)


MEASURED_DRAPE = GOOD.replace(
    "valid_strain = 0.03\n",
    "valid_strain = 0.03\nmeasured_dc = 0.62\nmeasured_dc_diameter = 0.30\n",
    1,
) + ('\nmeasured_dc = "measured: test paper, Table 2"\nmeasured_dc_diameter = "measured: test paper, 30 cm on 18 cm"')


def test_a_published_drape_coefficient_loads_with_its_specimen(tmp_path):
    e = load(_write(tmp_path, MEASURED_DRAPE))["x"]
    assert (e.measured_dc, e.measured_dc_diameter) == (0.62, 0.30)
    assert e.sources["measured_dc"].startswith("measured:")
    # the shipped entries carry none unless a paper measured the fabric their numbers describe
    assert load(_write(tmp_path, GOOD))["x"].measured_dc is None
    for name in fabrics.names():
        e = fabrics.entry(name)
        assert (e.measured_dc is None) == (e.measured_dc_diameter is None)
        if e.measured_dc is not None:
            assert e.sources["measured_dc"].startswith("measured:"), name


@pytest.mark.parametrize(
    "old,new,where",
    [
        ("measured_dc = 0.62", "measured_dc = 62.0", r"fabric\.x\.measured_dc: 62\.0 is outside"),
        ("measured_dc_diameter = 0.30\n", "", r"fabric\.x\.measured_dc_diameter: missing"),
        ("measured_dc_diameter = 0.30", "measured_dc_diameter = 0.18", r"not a Cusick specimen"),
        ('measured_dc = "measured: test paper, Table 2"', 'measured_dc = "estimate: about"', r"source\.measured_dc"),
    ],
)
def test_a_bad_published_drape_coefficient_is_named(tmp_path, old, new, where):
    assert old in MEASURED_DRAPE
    with pytest.raises(FabricLibraryError, match=where):
        load(_write(tmp_path, MEASURED_DRAPE.replace(old, new, 1)))
