"""The texture plugin `otbake_blend` against a `bitmap` of `otbake blend`'s EXR, in Mitsuba
renders (scalar_rgb).

Both textures are the radiance of an area light filling an orthographic view, rendered R times
with independent seeds (R = 16 renders of 4 samples per pixel each); per pixel, the two means must
agree within 6 standard errors of their difference (the standard error from the per-pixel sample
variance across the R renders, plus ``conftest.SE_FLOOR``: the noise is the pixel filter's random
positions inside the pixel, so it is largest where the texture varies across a pixel). Why 6: the
difference over its estimated error follows Student's t with about 2(R − 1) = 30 degrees of
freedom, P(|t| > 6) ≈ 1.3e-6 per pixel, so over 576 pixels noise alone fails about one seed set
in a thousand (the seeds are fixed: a run is reproducible). The EXR is 4× finer than the render and the kernel 2 EXR pixels wide, so
the bitmap's bilinear interpolation is a small bias next to that noise (its size is printed on
failure).
"""

import numpy as np

from conftest import run, z_scores

W = "0.2,0.5,0.3"
RES, EXR_RES, SIGMA_PX = 24, 96, 2.0
R, SPP = 16, 4


def scene(mi, texture, seed):
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 1},
            "sensor": {
                "type": "orthographic",
                "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 3], target=[0, 0, 0], up=[0, 1, 0]),
                "film": {"type": "hdrfilm", "width": RES, "height": RES, "rfilter": {"type": "box"}},
                "sampler": {"type": "independent", "sample_count": SPP, "seed": seed},
            },
            "plane": {"type": "rectangle", "emitter": {"type": "area", "radiance": texture}},
        }
    )


def renders(mi, texture, seeds):
    return np.stack([np.array(mi.render(scene(mi, texture, s)), dtype=np.float64) for s in seeds])


def test_texture_plugin_renders_as_a_bitmap_of_the_cli_exr(mi_scalar, shapes, otbake_bin, work):
    mi = mi_scalar
    exr = work / "texture.exr"
    run(otbake_bin, "blend", shapes, "--weights", W, "--size", f"{EXR_RES}x{EXR_RES}", "--sigma", SIGMA_PX, "-o", exr)
    bitmap = {"type": "bitmap", "filename": str(exr), "filter_type": "bilinear", "wrap_mode": "clamp"}
    plugin = {"type": "otbake_blend", "manifest": str(shapes), "weights": W, "sigma": SIGMA_PX / EXR_RES}
    a = renders(mi, bitmap, range(R))
    b = renders(mi, plugin, range(100, 100 + R))
    z, diff, se = z_scores(a, b)
    assert a.mean() > 0.05, "the render is black: the scene does not show the texture"
    assert np.abs(z).max() < 6, (np.abs(z).max(), np.abs(diff).max(), se.max())
    # The noise is small next to the signal: the comparison has power.
    assert np.median(se) < 0.05 * a.mean()


def test_a_weight_texture_gives_the_same_render_as_fixed_weights(mi_scalar, shapes):
    mi = mi_scalar
    fixed = {"type": "otbake_blend", "manifest": str(shapes), "weights": W, "sigma": 0.02}
    constant = {"type": "rgb", "value": [0.2, 0.5, 0.3]}
    textured = dict(fixed, weights={"type": "checkerboard", "color0": constant, "color1": constant})
    # The same seed: the same rays, so the renders must agree up to the weights' float rounding.
    a = np.array(mi.render(scene(mi, fixed, 7)))
    b = np.array(mi.render(scene(mi, textured, 7)))
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6)
    assert a.mean() > 0.05
