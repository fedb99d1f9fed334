"""The BSDF plugin `otbake_brdf` in Mitsuba's own terms (llvm_ad_rgb, whole wavefronts per call):
Mitsuba's χ² test of its sampling against its pdf at several incident angles, and its albedo
(the mean sample weight) never above 1 beyond noise. Also: the plugin renders in scalar_rgb."""

import numpy as np
import pytest

import otbake.mitsuba

# 80° passes too (p = 0.79 at res 41, D73) but costs as much as the other three together (the
# kernel estimate near the horizon reaches across the cube face): CI tests three angles.
ANGLES = [5.0, 30.0, 55.0]


@pytest.fixture
def mi_llvm():
    import drjit as dr
    import mitsuba as mi

    try:
        mi.set_variant("llvm_ad_rgb")
    except Exception as e:  # noqa: BLE001 - the message says what to install
        pytest.fail(f"mitsuba's llvm_ad_rgb variant does not load ({e}): apt-get install -y libllvm19")
    dr.set_thread_count(2)
    otbake.mitsuba.vectorize()
    otbake.mitsuba.register()
    return mi


def bsdf_dict(brdfs, weights="0.5,0.5"):
    return {"type": "otbake_brdf", "manifest": str(brdfs), "weights": weights}


def direction(deg):
    t = np.radians(deg)
    return [float(np.sin(t)), 0.0, float(np.cos(t))]


@pytest.mark.parametrize("theta", ANGLES)
def test_sampling_passes_mitsubas_chi2_test(mi_llvm, brdfs, theta, tmp_path, monkeypatch):
    from mitsuba.chi2 import BSDFAdapter, ChiSquareTest, SphericalDomain

    monkeypatch.chdir(tmp_path)  # a failing test writes chi2_data.py into the working directory
    sample, pdf = BSDFAdapter("otbake_brdf", bsdf_dict(brdfs), wi=direction(theta))
    chi2 = ChiSquareTest(
        domain=SphericalDomain(), sample_func=sample, pdf_func=pdf, sample_dim=3, sample_count=200_000, res=41, ires=8
    )
    assert chi2.run(), chi2.messages


@pytest.mark.parametrize("theta", [5.0, 45.0, 70.0])
@pytest.mark.parametrize("weights", ["1,0", "0.3,0.7", "0,1"])
def test_albedo_never_exceeds_one(mi_llvm, brdfs, theta, weights):
    """Up to θi = 70°: at 80° the cayman input's own albedo (its eval integrated directly, no
    sampling involved) is about 3 in this 16³ bake — a property of the data, which the sampled
    estimate reproduces (test_sampled_albedo_is_the_integrated_albedo)."""
    import drjit as dr

    mi = mi_llvm
    bsdf = mi.load_dict(bsdf_dict(brdfs, weights))
    n = 20_000
    rng = np.random.default_rng(int(theta))
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(*direction(theta))
    bs, weight = bsdf.sample(mi.BSDFContext(), si, mi.Float(rng.random(n)), mi.Point2f(rng.random(n), rng.random(n)))
    w = _channels(weight)
    mean, se = w.mean(axis=1), w.std(axis=1) / np.sqrt(n)
    assert np.all(mean <= 1 + 4 * se), (mean, se)
    assert np.all(mean > 0)
    _agrees_with_integral(mi, bsdf, si, theta, mean, se, rng, n)


@pytest.mark.parametrize("theta", [80.0])
def test_sampled_albedo_is_the_integrated_albedo(mi_llvm, brdfs, theta):
    """Where the data's albedo exceeds 1, the BSDF's samples still estimate exactly it."""
    import drjit as dr

    mi = mi_llvm
    bsdf = mi.load_dict(bsdf_dict(brdfs, "0.3,0.7"))
    n = 20_000
    rng = np.random.default_rng(int(theta))
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(*direction(theta))
    _, weight = bsdf.sample(mi.BSDFContext(), si, mi.Float(rng.random(n)), mi.Point2f(rng.random(n), rng.random(n)))
    w = _channels(weight)
    mean, se = w.mean(axis=1), w.std(axis=1) / np.sqrt(n)
    _agrees_with_integral(mi, bsdf, si, theta, mean, se, rng, n)


def _channels(color):
    a = np.array(color, dtype=np.float64)
    return a.reshape(3, -1) if a.shape[0] == 3 else a.T


def _agrees_with_integral(mi, bsdf, si, theta, mean, se, rng, n):
    """The sampled estimate agrees with the albedo integrated with uniform directions (eval only)."""
    wo = rng.standard_normal((n, 3))
    wo[:, 2] = np.abs(wo[:, 2])
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    f = bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(wo[:, 0], wo[:, 1], wo[:, 2]))
    g = _channels(f) * 2 * np.pi
    se2 = np.hypot(se, g.std(axis=1) / np.sqrt(n))
    assert np.all(np.abs(mean - g.mean(axis=1)) < 5 * se2), (mean, g.mean(axis=1), se2)


def test_bsdf_renders_spheres_in_scalar_rgb(mi_scalar, brdfs):
    mi = mi_scalar
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 2},
            "sensor": {
                "type": "perspective",
                "fov": 30,
                "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
                "film": {"type": "hdrfilm", "width": 12, "height": 12},
                "sampler": {"type": "independent", "sample_count": 4},
            },
            "light": {"type": "directional", "direction": [-1, -1, -1], "irradiance": 3.0},
            "sphere": {"type": "sphere", "bsdf": bsdf_dict(brdfs)},
        }
    )
    img = np.array(mi.render(scene))
    assert np.isfinite(img).all() and img.max() > 0
