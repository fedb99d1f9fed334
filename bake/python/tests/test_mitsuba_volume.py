"""The volume plugin against a `gridvolume` of `otbake volume`'s `.vol`, as the density of a
heterogeneous medium in Mitsuba renders (scalar_rgb, volpath).

A purely absorbing medium (albedo 0) in the unit cube in front of a constant environment:
each pixel is the transmittance, estimated by delta tracking (every path is 0 or 1). Each medium
is rendered R = 16 times (4 samples per pixel) with independent seeds; per pixel the two means
must agree within 6 standard errors of their difference (from the per-pixel sample variance across
the R renders), for the reasons the texture test gives (256 pixels here). The grid is 64³ for a kernel of sigma 0.03 (a cell is half a sigma), so its trilinear
interpolation is a small bias next to the noise.
"""

import numpy as np

import otbake.mitsuba
from conftest import run, z_scores

RES, R, SPP, SCALE = 16, 16, 4, 4.0


def scene(mi, density, seed):
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "volpath", "max_depth": 4},
            "sensor": {
                "type": "orthographic",
                "to_world": mi.ScalarTransform4f().look_at(origin=[0.5, 0.5, 3], target=[0.5, 0.5, 0.5], up=[0, 1, 0])
                @ mi.ScalarTransform4f().scale([0.5, 0.5, 1]),
                "film": {"type": "hdrfilm", "width": RES, "height": RES, "rfilter": {"type": "box"}},
                "sampler": {"type": "independent", "sample_count": SPP, "seed": seed},
            },
            "light": {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
            "cube": {
                "type": "cube",
                "to_world": mi.ScalarTransform4f().translate([0.5, 0.5, 0.5]) @ mi.ScalarTransform4f().scale(0.5),
                "bsdf": {"type": "null"},
                "interior": {"type": "heterogeneous", "albedo": 0.0, "sigma_t": density, "scale": SCALE},
            },
        }
    )


def renders(mi, density, seeds):
    return np.stack([np.array(mi.render(scene(mi, density, s)), dtype=np.float64) for s in seeds])


def test_volume_plugin_renders_as_a_gridvolume_of_the_cli_vol(mi_scalar, volumes, otbake_bin, work):
    mi = mi_scalar
    vol = work / "medium.vol"
    run(otbake_bin, "volume", volumes, "--weights", "0.4,0.6", "--res", 64, "--sigma", 0.03, "-o", vol)
    grid = mi.load_dict({"type": "gridvolume", "filename": str(vol)})
    plugin = otbake.mitsuba.volume(volumes, [0.4, 0.6], 0.03)
    assert plugin.max() >= grid.max(), "the plugin's majorant must bound the density"
    a = renders(mi, grid, range(R))
    b = renders(mi, plugin, range(100, 100 + R))
    z, diff, se = z_scores(a, b)
    # The medium shows: some pixels are dark, the corners see the background.
    assert a.mean(0).min() < 0.5 and a.mean(0)[0, 0, 0] > 0.95
    assert np.abs(z).max() < 6, (np.abs(z).max(), np.abs(diff).max(), se.max())
