"""The README's picture: spheres of blended BRDFs rendered by Mitsuba 3 with the otbake BSDF.

    python bake/python/examples/spheres.py docs/mitsuba-spheres.png

Bakes two Cornell BRDFs (cayman, a car paint, and garnet red) at 20000 points into
target/spheres, then renders five spheres from all-cayman to all-garnet under an environment and a
sun in llvm_ad_rgb (whole wavefronts per plugin call).
"""

import sys
from pathlib import Path

import drjit as dr
import mitsuba as mi
import numpy as np

import otbake
import otbake.mitsuba

REPO = Path(__file__).resolve().parents[3]
DATA = (REPO / ".." / "shared" / "data" / "brdfs").resolve()

out = Path(sys.argv[1] if len(sys.argv) > 1 else "spheres.png")
manifest = REPO / "target" / "spheres" / "brdfs.toml"
manifest.parent.mkdir(parents=True, exist_ok=True)
manifest.write_text(
    f'[output]\ndir = "{manifest.parent}/out"\n[proxy]\nkind = "gaussian"\nsamples = 20000\nseed = 0\n'
    f'[solver]\nkind = "sliced"\n[brdf]\nresolution = 24\n'
    f'[[input]]\nname = "cayman"\npath = "{DATA}/cornell_cayman.brdf"\n'
    f'[[input]]\nname = "garnet_red"\npath = "{DATA}/cornell_garnet_red.brdf"\n'
)
otbake.bake(manifest)

mi.set_variant("llvm_ad_rgb")
dr.set_thread_count(2)
otbake.mitsuba.vectorize()
otbake.mitsuba.register()
scene = {
    "type": "scene",
    "integrator": {"type": "path", "max_depth": 2},
    "sensor": {
        "type": "perspective",
        "fov": 34,
        "to_world": mi.ScalarTransform4f().look_at(origin=[0, 1.2, 12], target=[0, 0, 0], up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": 320, "height": 80},
        "sampler": {"type": "independent", "sample_count": 16},
    },
    "env": {"type": "constant", "radiance": {"type": "rgb", "value": 0.35}},
    "sun": {"type": "directional", "direction": [-0.4, -0.6, -0.7], "irradiance": 2.5},
}
for i, t in enumerate(np.linspace(0, 1, 5)):
    scene[f"s{i}"] = {
        "type": "sphere",
        "center": [(i - 2) * 1.25, 0, 0],
        "radius": 0.55,
        "bsdf": {"type": "otbake_brdf", "manifest": str(manifest), "weights": f"{1 - t},{t}"},
    }
img = mi.render(mi.load_dict(scene))
mi.util.write_bitmap(str(out), img)
print(out)
