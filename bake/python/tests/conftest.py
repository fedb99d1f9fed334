"""Shared fixtures: small manifests baked once per session into a temporary directory, the
`otbake` CLI binary the comparisons run, and Mitsuba set up for the plugin tests."""

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import otbake

REPO = Path(__file__).resolve().parents[3]
SHARED = (REPO / ".." / "shared" / "data").resolve()


def manifest_text(out, body, samples, solver="exact"):
    return f"""
[output]
dir = "{out}"

[proxy]
kind = "gaussian"
samples = {samples}
seed = 0

[solver]
kind = "{solver}"
{body}
"""


SHAPES = """
[[input]]
name = "duck"
path = "{d}/shapes/duck.png"
density = "inverted"

[[input]]
name = "heart"
path = "{d}/shapes/heart.png"
density = "inverted"

[[input]]
name = "tooth"
path = "{d}/shapes/tooth.png"
density = "inverted"
"""

BRDFS = """
[brdf]
resolution = 16

[[input]]
name = "cayman"
path = "{d}/brdfs/cornell_cayman.brdf"

[[input]]
name = "garnet_red"
path = "{d}/brdfs/cornell_garnet_red.brdf"
"""

VOLUMES = """
[mesh]
resolution = 24
fit = "each"
margin = 0.1

[[input]]
name = "torus"
path = "{d}/meshes/torus.obj"

[[input]]
name = "monkey"
path = "{d}/meshes/suzanne.obj"
"""


@pytest.fixture(scope="session")
def work(tmp_path_factory):
    return tmp_path_factory.mktemp("otbake")


def _manifest(work, name, body, samples, solver="exact"):
    if not SHARED.is_dir():
        pytest.fail(f"the shared assets are missing: {SHARED} must exist beside the repository")
    path = work / f"{name}.toml"
    path.write_text(manifest_text(work / name, body.format(d=SHARED), samples, solver))
    otbake.bake(path)
    return path


@pytest.fixture(scope="session")
def shapes(work):
    """Three 2D shapes, 1500 points, baked."""
    return _manifest(work, "shapes", SHAPES, 1500)


@pytest.fixture(scope="session")
def brdfs(work):
    """Two Cornell BRDFs at 16³ cells, 20000 points (sliced maps: a BSDF test needs dense points,
    not exact maps; with few points the kernel estimate has holes, where the BSDF is 0), baked."""
    return _manifest(work, "brdfs", BRDFS, 20000, "sliced")


@pytest.fixture(scope="session")
def volumes(work):
    """Two meshes voxelized at 24³, 2000 points, baked."""
    return _manifest(work, "volumes", VOLUMES, 2000)


@pytest.fixture(scope="session")
def otbake_bin():
    """The `otbake` CLI (OTBAKE_BIN, or target/release/otbake of this checkout)."""
    path = Path(os.environ.get("OTBAKE_BIN", REPO / "target" / "release" / "otbake"))
    if not path.is_file():
        pytest.fail(f"{path} is missing: run `cargo build --release -p otbake` (or set OTBAKE_BIN)")
    return path


def run(bin_, *args):
    subprocess.run([str(bin_), *map(str, args)], check=True, capture_output=True)


@pytest.fixture
def mi_scalar():
    """Mitsuba in scalar_rgb, with the otbake plugins registered (set for every test: the χ²
    tests switch to llvm_ad_rgb)."""
    import mitsuba as mi
    import drjit as dr

    mi.set_variant("scalar_rgb")
    # Bitmap EXR I/O deadlocks with one Dr.Jit thread (a one-CPU runner): never run with one.
    dr.set_thread_count(max(2, os.cpu_count() or 2))
    import otbake.mitsuba

    otbake.mitsuba.register()
    return mi


def read_exr(mi, path):
    """An EXR as a float32 array (h, w, channels)."""
    return np.array(mi.Bitmap(str(path)), dtype=np.float32)


def pixel_centres(w, h):
    """Pixel centres of a w×h image in the blend's domain, row by row: (h·w, 2) float32."""
    x = (np.arange(w, dtype=np.float32) + 0.5) / np.float32(w)
    y = (np.arange(h, dtype=np.float32) + 0.5) / np.float32(h)
    X, Y = np.meshgrid(x, y)
    return np.ascontiguousarray(np.stack([X, Y], axis=-1).reshape(-1, 2))


#: Added to every standard error: a pixel whose samples all agree (the background) still differs
#: between renders by the film's float rounding (a few 1e-8), which must not count as a difference.
SE_FLOOR = 1e-4


def z_scores(a, b):
    """Per-pixel z-scores of the difference of two sets of independent renders (R, h, w, c):
    the difference of the means over its standard error, from the per-pixel sample variance
    across the R renders of each set (plus ``SE_FLOOR``)."""
    r = a.shape[0]
    diff = a.mean(0) - b.mean(0)
    se = np.sqrt((a.var(0, ddof=1) + b.var(0, ddof=1)) / r) + SE_FLOOR
    return diff / se, diff, se
