import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from shellbuckle.params import (PhysicalRangeWarning, ShellParameters, check_caption, d_over_R,
                                gamma_from_d_over_R, thickness_factor)

# The paper's reference values (shared with the reproduction report), shipped with the package.
_REFERENCE = [Path(__file__).resolve().parents[1] / "src" / "shellbuckle" / "data"
              / "quilliet2008.json"]

# Caption pairs as printed in Quilliet et al. (2008): Fig. 4 (gamma = 743, "d/R = 0.116"),
# Fig. 7 (271 -> 0.172, 2333 -> 0.0586, 20995 -> 0.0195), Fig. 8 (2916 -> 0.064), nu = 1/3.
_CAPTIONS = [(271, 0.172, True), (743, 0.116, False), (2333, 0.0586, True),
             (2916, 0.064, False), (20995, 0.0195, True)]


def _reference_captions():
    for path in _REFERENCE:
        if path.is_file():
            data = json.loads(path.read_text())
            return [(c["gamma"], c["d_over_R"], c["consistent"])
                    for c in data["gamma_to_d_over_R_in_captions"]]
    pytest.skip("reference/quilliet2008.json not found next to the repository")


def test_reference_file_captions_are_classified_as_the_paper_text_says():
    for gamma, ratio, consistent in _reference_captions():
        assert check_caption(gamma, ratio, nu=1 / 3) is consistent, (gamma, ratio)


@pytest.mark.parametrize("gamma, ratio, consistent", _CAPTIONS)
def test_caption_pairs(gamma, ratio, consistent):
    assert check_caption(gamma, ratio, nu=1 / 3) is consistent
    # the paper prints nu = 0.333 in those captions: same verdict
    assert check_caption(gamma, ratio, nu=0.333) is consistent
    if consistent:  # to the caption's rounding: half a unit in the last printed digit
        half_unit = 0.5 * 10.0 ** -(len(repr(ratio).split(".")[1]))
        assert abs(ShellParameters.from_gamma(gamma).d_over_R - ratio) <= half_unit


def test_check_caption_reads_the_printed_precision():
    exact = d_over_R(2333, 1 / 3)  # 0.058558...
    assert check_caption(2333, "0.0586", 1 / 3)
    assert check_caption(2333, "0.06", 1 / 3)  # coarser print still agrees
    assert not check_caption(2333, "0.05860", 1 / 3)  # five digits claim too much
    assert check_caption(2333, f"{exact:.8f}", 1 / 3)


def test_gamma_formula_at_one_third_is_eight_over_square():
    # 1 - 2 nu^2/(1 - nu) = 2/3 at nu = 1/3, so gamma = 8 (R/d)^2 (reference conventions)
    assert math.isclose(thickness_factor(1 / 3), 2 / 3, rel_tol=1e-15)
    ratio = np.array([0.01, 0.05, 0.2])
    np.testing.assert_allclose(gamma_from_d_over_R(ratio, 1 / 3), 8 / ratio ** 2, rtol=1e-14)
    np.testing.assert_allclose(d_over_R(gamma_from_d_over_R(ratio, 0.2), 0.2), ratio, rtol=1e-14)


@pytest.mark.parametrize("sigma", [-0.3, 0.0, 0.25, 0.5])
def test_from_material_matches_the_paper_moduli(sigma):
    E, d, R = 2.5e9, 1.5e-8, 8.7e-7
    p = ShellParameters.from_material(E=E, sigma=sigma, d=d, R=R)
    kappa = E * d ** 3 / (12 * (1 - sigma ** 2))
    A = (1 + 2 * sigma) / (1 + sigma) ** 2 * E * d
    assert math.isclose(p.kappa, kappa, rel_tol=1e-14)
    assert math.isclose(p.A, A, rel_tol=1e-12)
    assert math.isclose(p.gamma, A * R ** 2 / kappa, rel_tol=1e-14)
    assert math.isclose(p.nu, sigma / (1 + sigma), rel_tol=1e-14, abs_tol=1e-16)
    # gamma = 12 (1 - 2 sigma^2/(1 + sigma)) (R/d)^2, the sigma form of eq. DefFvK_lambda
    assert math.isclose(p.gamma, 12 * (1 - 2 * sigma ** 2 / (1 + sigma)) * (R / d) ** 2,
                        rel_tol=1e-12)
    assert math.isclose(p.d_over_R, d / R, rel_tol=1e-12)
    assert math.isclose(p.sigma, sigma, rel_tol=1e-12, abs_tol=1e-15)
    assert ShellParameters.from_dict(p.to_dict()) == p
    assert ShellParameters.from_dict(json.loads(json.dumps(p.to_dict()))) == p


def test_from_gamma_units_and_round_trip():
    p = ShellParameters.from_gamma(2333)
    assert (p.gamma, p.nu, p.kappa, p.R, p.A) == (2333.0, 1 / 3, 1.0, 1.0, 2333.0)
    q = ShellParameters.from_gamma(500, nu=0.2, kappa=3.0, R=2.0)
    assert math.isclose(q.A, 500 * 3.0 / 4.0)
    assert ShellParameters.from_dict(q.to_dict()) == q
    assert "gamma = 2333" in p.describe() and "d/R = 0.05856" in p.describe()
    with pytest.raises(Exception):
        p.gamma = 3.0  # frozen


def test_from_dict_refuses_edited_or_unknown_entries():
    data = ShellParameters.from_gamma(2333).to_dict()
    with pytest.raises(ValueError, match="d_over_R"):
        ShellParameters.from_dict({**data, "d_over_R": 0.06})
    with pytest.raises(ValueError, match="gama"):
        ShellParameters.from_dict({**data, "gama": 1.0})


@pytest.mark.parametrize("kwargs, name", [
    (dict(gamma=0.0), "gamma"), (dict(gamma=-1.0), "gamma"), (dict(gamma=np.inf), "gamma"),
    (dict(gamma=np.nan), "gamma"), (dict(gamma=100, nu=1.0), "nu"),
    (dict(gamma=100, nu=-1.0), "nu"), (dict(gamma=100, nu=np.nan), "nu"),
    (dict(gamma=100, kappa=0.0), "kappa"), (dict(gamma=100, kappa=np.nan), "kappa"),
    (dict(gamma=100, R=-1.0), "R"), (dict(gamma=100, R=np.nan), "R"),
])
def test_bad_dimensionless_values_are_refused_by_name(kwargs, name):
    with pytest.raises(ValueError, match=rf"\b{name}\b"):
        ShellParameters.from_gamma(**kwargs)


@pytest.mark.parametrize("kwargs, name", [
    (dict(sigma=0.6), "sigma"), (dict(sigma=-1.0), "sigma"), (dict(sigma=-0.7), "sigma"),
    (dict(sigma=np.nan), "sigma"), (dict(d=0.0), "d"), (dict(d=-0.1), "d"), (dict(d=1.0), "d"),
    (dict(d=2.0), "d"), (dict(d=np.nan), "d"), (dict(R=0.0), "R"), (dict(R=np.nan), "R"),
    (dict(E=0.0), "E"), (dict(E=-5.0), "E"), (dict(E=np.nan), "E"),
])
def test_bad_material_values_are_refused_by_name(kwargs, name):
    good = dict(E=1e9, sigma=0.5, d=0.05, R=1.0)
    with pytest.raises(ValueError, match=rf"\b{name}\b"):
        ShellParameters.from_material(**{**good, **kwargs})


def test_error_message_states_the_allowed_range():
    with pytest.raises(ValueError, match=r"\(-1, 1\)"):
        ShellParameters.from_gamma(100, nu=2.0)
    with pytest.raises(ValueError, match=r"\(-1, 0.5\]"):
        ShellParameters.from_material(E=1.0, sigma=0.7, d=0.1, R=1.0)


def test_nu_above_one_third_warns_and_thickness_needs_positive_factor():
    with pytest.warns(PhysicalRangeWarning, match="1/3"):
        p = ShellParameters.from_gamma(1000, nu=0.4)
    # 1 - 2 nu^2/(1 - nu) = 1 - 0.32/0.6 > 0: d/R defined
    assert math.isclose(p.d_over_R, math.sqrt(12 * (1 - 0.32 / 0.6) / 1000), rel_tol=1e-14)
    with pytest.warns(PhysicalRangeWarning):
        q = ShellParameters.from_gamma(1000, nu=0.5)  # factor 1 - 0.5/0.5 = 0
    with pytest.raises(ValueError, match="nu"):
        q.d_over_R
    assert "d_over_R" not in q.to_dict()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ShellParameters.from_gamma(1000, nu=1 / 3)  # the incompressible limit does not warn
        ShellParameters.from_gamma(1000, nu=-0.5)


def test_inconsistent_material_fields_are_refused():
    with pytest.raises(ValueError, match="together"):
        ShellParameters(gamma=100.0, E=1.0)
    good = ShellParameters.from_material(E=1e9, sigma=0.5, d=0.05, R=1.0)
    with pytest.raises(ValueError, match="gamma"):
        ShellParameters(gamma=2 * good.gamma, nu=good.nu, kappa=good.kappa, R=good.R,
                        E=good.E, d=good.d)
