"""Noise floors of the analysis thresholds, with margins (docs/analysis.md, "Calibration").

The tests assert that shapes whose true answer is known (a sphere has no dent; an inverted cap
is axisymmetric) stay well inside the thresholds on both mesh kinds, at two resolutions and in
random orientations. Run as a script to print the calibration tables of docs/analysis.md::

    python tests/test_analysis_calibration.py [RUN_DIR ...]

(run folders are optional: their capsule steps are added to the axisymmetry noise floor).
"""

import sys

import numpy as np
import pytest

from shellbuckle.analysis import ShapeAnalyzer
from shellbuckle.analysis.classify import AXISYMMETRY_EDGES
from shellbuckle.analysis.descriptors import MIN_DENT_RADIUS
from shellbuckle.mesh import icosphere, random_sphere

from test_analysis_shapes import inverted_cap, jiggled, rotation

MESHES = {"icosphere(8)": lambda: icosphere(8), "icosphere(19)": lambda: icosphere(19),
          "random(642)": lambda: random_sphere(642, seed=3),
          "random(3594)": lambda: random_sphere(3594, seed=4)}
_cache = {}


def _mesh(name):
    if name not in _cache:
        m = MESHES[name]()
        _cache[name] = (m, ShapeAnalyzer(m.topology, contact=False))
    return _cache[name]


def jiggle_floor(name, amplitude, trials=3, seed=0):
    """Smallest smoothed H and largest equivalent radius sqrt(area/pi) of an inverted
    component over ``trials`` spheres jiggled by ``amplitude`` mean edge lengths."""
    m, an = _mesh(name)
    rng = np.random.default_rng(seed)
    h = an.geometry(m.X).mean_edge
    H_min, radius = np.inf, 0.0
    for _ in range(trials):
        g = an.geometry(jiggled(m.X, amplitude * h, rng))
        H_min = min(H_min, float(g.H_smooth.min()))
        comps = an.inverted_components(g)
        if comps:
            radius = max(radius, float(np.sqrt(comps[0].area / np.pi)))
    return H_min, radius


def cap_floor(name, alpha_deg, trials=4, seed=0):
    """Largest ``amplitude * radius / h`` of the modes m >= 2 of the crest and of the outline
    over ``trials`` random orientations of an inverted cap (true value 0)."""
    m, an = _mesh(name)
    rng = np.random.default_rng(seed + alpha_deg)
    crest = outline = 0.0
    for _ in range(trials):
        X = inverted_cap(m.X, np.radians(alpha_deg), rng.normal(size=3)) @ rotation(rng).T
        d = an.describe(X)
        if d.rim is None:
            return np.nan, np.nan
        h = d.geometry.mean_edge
        crest = max(crest, d.rim.crest.dominant_amplitude * d.rim.crest.radius / h)
        outline = max(outline, d.rim.outline.dominant_amplitude * d.rim.outline.radius / h)
    return crest, outline


@pytest.mark.parametrize("name", ["icosphere(19)", "random(3594)", "random(642)"])
def test_spheres_jiggled_by_a_tenth_of_an_edge_have_no_inverted_region(name):
    H_min, radius = jiggle_floor(name, 0.1)
    assert H_min > 0 and radius == 0.0


@pytest.mark.parametrize("name", ["icosphere(19)", "random(3594)"])
def test_rough_spheres_give_no_dent(name):
    # at 20 % of an edge, inverted patches appear but stay well below the dent size
    H_min, radius = jiggle_floor(name, 0.2)
    assert radius < 0.5 * MIN_DENT_RADIUS


@pytest.mark.parametrize("name", ["icosphere(19)", "random(3594)"])
@pytest.mark.parametrize("alpha_deg", [30, 60, 85])
def test_inverted_caps_are_axisymmetric_with_margin(name, alpha_deg):
    crest, outline = cap_floor(name, alpha_deg, trials=2)
    assert max(crest, outline) < 0.5 * AXISYMMETRY_EDGES


def main(run_dirs):
    print("Jiggled spheres: min smoothed H (1/R) / largest inverted equivalent radius (R)")
    amplitudes = [0.01, 0.03, 0.1, 0.2, 0.3]
    print("| mesh | " + " | ".join(f"{a:g} h" for a in amplitudes) + " |")
    print("|---" * (len(amplitudes) + 1) + "|")
    for name in MESHES:
        cells = [jiggle_floor(name, a) for a in amplitudes]
        print(f"| {name} | " + " | ".join(f"{H:.2f} / {r:.3f}" for H, r in cells) + " |")
    print("\nInverted caps: max over 4 orientations of amplitude * radius / h, crest / outline")
    alphas = [20, 30, 45, 60, 75, 85]
    print("| mesh | " + " | ".join(f"{a} deg" for a in alphas) + " |")
    print("|---" * (len(alphas) + 1) + "|")
    for name in MESHES:
        cells = [cap_floor(name, a) for a in alphas]
        print(f"| {name} | " + " | ".join(
            "no dent" if np.isnan(c) else f"{c:.3f} / {o:.3f}" for c, o in cells) + " |")
    if run_dirs:
        from shellbuckle.analysis import classify_run

        print("\nRuns: capsule steps, max amplitude * radius / h of the outline (and crest)")
        for path in run_dirs:
            results = classify_run(path)
            ratios = [(c.dominant_amplitude * c.rim_radius / c.descriptors.geometry.mean_edge,
                       c.descriptors.rim.crest.dominant_amplitude * c.crest_radius
                       / c.descriptors.geometry.mean_edge)
                      for c in results.values() if c.shape == "capsule"]
            shapes = {}
            for c in results.values():
                shapes[c.shape] = shapes.get(c.shape, 0) + 1
            if ratios:
                o, c = np.max(ratios, axis=0)
                print(f"{path}: {shapes}; capsule noise outline {o:.3f}, crest {c:.3f}")
            else:
                print(f"{path}: {shapes}")


if __name__ == "__main__":
    main(sys.argv[1:])
