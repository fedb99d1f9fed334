"""Bad input: every function checks its arrays (type, shape, dtype, contiguity) and weights, and
raises an otbake.Error subclass whose message names the argument."""

import numpy as np
import pytest

import otbake

W = [0.2, 0.5, 0.3]


@pytest.fixture(scope="module")
def blend(shapes):
    return otbake.open_manifest(shapes)


@pytest.fixture(scope="module")
def brdf(brdfs):
    return otbake.open_manifest(brdfs, brdf=True)


P = np.full((4, 2), 0.5, np.float32)


@pytest.mark.parametrize(
    "points, words",
    [
        ([[0.5, 0.5]], "points must be a numpy array"),
        (np.full((4, 2), 0.5), "points has dtype float64, it must be float32"),
        (np.full((4, 3), 0.5, np.float32), "points has shape [4, 3], it must be (n, 2)"),
        (np.full(4, 0.5, np.float32), "points has shape [4], it must be (n, 2)"),
        (np.full((2, 4), 0.5, np.float32).T, "points is not C-contiguous"),
        (np.asfortranarray(np.full((4, 2), 0.5, np.float32))[:, ::-1], "points is not C-contiguous"),
        (np.array([[0.5, np.nan]], np.float32), "points[0]: a query coordinate is NaN"),
    ],
)
def test_points_are_checked(blend, points, words):
    with pytest.raises(otbake.Error) as e:
        blend.point(W, points, 0.02)
    assert words in str(e.value)
    assert isinstance(e.value, ValueError)


@pytest.mark.parametrize(
    "weights, words",
    [
        ([0.5, 0.5], "weights has 2 values for 3 maps"),
        ([0.5, 0.6, -0.1], "weights: the weight at index 2 (counting from 0, in manifest order) is negative"),
        ([0.5, 0.5, 0.5], "weights: weights sum to 1.5"),
        (np.array(W), "weights has dtype float64, it must be float32"),
        (np.full((3, 3), 1 / 3, np.float32), "weights has shape [3, 3], it must be (3,) or (4, 3)"),
        ("0.3,0.3,0.4", "weights must be a sequence of 3 numbers"),
        (np.array([[0.2, 0.5, 0.3]] * 3 + [[0.9, 0.9, 0.9]], np.float32), "weights[3]: weights sum to"),
    ],
)
def test_weights_are_checked(blend, weights, words):
    with pytest.raises(otbake.QueryError if "sum" in words or "negative" in words else otbake.ArgumentError) as e:
        blend.point(weights, P, 0.02)
    assert words in str(e.value)


def test_kernel_and_indices_and_boxes_are_checked(blend):
    with pytest.raises(otbake.QueryError, match="kernel: kernel sigma must be a positive"):
        blend.point(W, P, -1.0)
    with pytest.raises(otbake.QueryError, match="kernel: "):
        blend.point_adaptive(W, P, 2.0, 0.1, 0.01)
    with pytest.raises(otbake.QueryError, match=r"indices\[1\]: sample index 99999 is out of range"):
        blend.sample(W, np.array([0, 99999], np.uint32))
    with pytest.raises(otbake.ArgumentError, match="indices has dtype int64, it must be uint32"):
        blend.sample(W, np.array([0, 1]))
    with pytest.raises(otbake.ArgumentError, match="hi has 3 rows but lo has 4"):
        blend.range(W, P, P[:3].copy())
    with pytest.raises(otbake.ArgumentError, match="res is"):
        blend.splat(W, (16,), 0.02)
    with pytest.raises(otbake.ArgumentError, match="res is"):
        blend.splat(W, (16, 0), 0.02)
    with pytest.raises(otbake.ArgumentError, match=r"weights has shape \[2, 3\]"):
        blend.splat(np.full((2, 3), 1 / 3, np.float32), (8, 8), 0.02)


def test_a_splat_larger_than_memory_is_refused_not_an_abort(blend):
    # Found by bake/python/fuzz: 65536 × 65536 cells with color asked for 51.5 GB and the
    # allocation failure aborted the interpreter. Refused before allocating, naming res and the fix.
    with pytest.raises(otbake.ArgumentError) as e:
        blend.splat(W, [65536, 65536], 0.02)
    message = str(e.value)
    assert "res [65536, 65536]" in message and "more than the budget" in message, message
    assert "use a smaller res" in message, message


def test_brdf_arguments_are_checked(brdf, brdfs):
    d = np.array([[0.0, 0.0, 1.0]])
    with pytest.raises(otbake.ArgumentError, match="wi has dtype float32, it must be float64"):
        brdf.eval([0.5, 0.5], d.astype(np.float32), d)
    with pytest.raises(otbake.ArgumentError, match=r"wo has shape \[1, 2\], it must be \(n, 3\)"):
        brdf.pdf([0.5, 0.5], d, d[:, :2].copy())
    with pytest.raises(otbake.ArgumentError, match="xi has shape"):
        brdf.sample([0.5, 0.5], np.zeros(1, np.uint32), np.zeros((1, 3)))
    with pytest.raises(otbake.QueryError, match="weights: weights sum to 2"):
        brdf.eval([1.0, 1.0], d, d)
    proxy_path, maps = otbake.archives(brdfs)
    parts = (otbake.Proxy.open(proxy_path), [otbake.Map.open(p) for _, p in maps])
    with pytest.raises(otbake.ArgumentError, match="not both"):
        otbake.BrdfBlend(*parts, sigma=0.02, adaptive=(2.0, 0.001, 0.03))
    with pytest.raises(otbake.QueryError, match="kernel sigma must be"):
        otbake.BrdfBlend(*parts, sigma=-1.0)


def test_archives_are_checked(shapes, brdfs, tmp_path):
    proxy_path, maps = otbake.archives(shapes)
    data = open(maps[0][1], "rb").read()
    with pytest.raises(otbake.ArchiveError):
        otbake.Map.open(data[: len(data) // 2])
    flipped = bytearray(data)
    flipped[len(flipped) // 2] ^= 0xFF
    with pytest.raises(otbake.ArchiveError):
        otbake.Map.open(flipped)
    with pytest.raises(otbake.ArchiveError, match="cannot open"):
        otbake.Map.open(tmp_path / "missing.otb")
    with pytest.raises(otbake.ArgumentError, match="source must be a path"):
        otbake.Map.open(12)
    # A map of another bake.
    _, other = otbake.archives(brdfs)
    with pytest.raises(otbake.QueryError, match="maps: map 0 was baked against another proxy"):
        otbake.Blend(otbake.Proxy.open(proxy_path), [otbake.Map.open(other[0][1])])
    with pytest.raises(otbake.QueryError, match="at least one map"):
        otbake.Blend(otbake.Proxy.open(proxy_path), [])


def test_manifests_and_bakes_are_checked(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[proxy]\nkind = 3\n")
    with pytest.raises(otbake.ManifestError, match="bad.toml"):
        otbake.bake(bad)
    with pytest.raises(otbake.ManifestError):
        otbake.bake(tmp_path / "missing.toml")
    (tmp_path / "nope.png").write_bytes(b"not a png")
    broken = tmp_path / "broken.toml"
    broken.write_text(
        f'[output]\ndir = "{tmp_path / "out"}"\n[proxy]\nkind = "gaussian"\nsamples = 100\n[solver]\nkind = "exact"\n'
        f'[[input]]\nname = "a"\npath = "{tmp_path / "nope.png"}"\n'
    )
    with pytest.raises(otbake.BakeError) as e:
        otbake.bake(broken)
    assert "nope.png" in str(e.value) and e.value.report["products"]


@pytest.mark.parametrize(
    "weights, error, words",
    [
        ([0.5, 0.5], otbake.ArgumentError, "weights has 2 values for 3 maps"),
        ([0.5, 0.6, -0.1], otbake.QueryError, "weights: the weight at index 2 (counting from 0, in manifest order) is negative"),
        ([0.5, 0.5, 0.5], otbake.QueryError, "weights: weights sum to 1.5"),
        (np.array(W), otbake.ArgumentError, "weights has dtype float64, it must be float32"),
        (np.full((2, 3), 1 / 3, np.float32), otbake.ArgumentError, "weights has shape [2, 3]"),
        (np.full((1, 3), 1 / 3, np.float32), otbake.ArgumentError, "one vector of 3 numbers"),
        ("0.3,0.3,0.4", otbake.ArgumentError, "weights must be a sequence of 3 numbers"),
    ],
)
def test_prepare_checks_its_weights(blend, weights, error, words):
    with pytest.raises(error) as e:
        blend.prepare(weights)
    assert words in str(e.value)


def test_prepared_queries_check_their_arguments(blend):
    pr = blend.prepare(W)
    with pytest.raises(otbake.ArgumentError, match="points has dtype float64, it must be float32"):
        pr.point(np.full((4, 2), 0.5), 0.02)
    with pytest.raises(otbake.ArgumentError, match=r"points has shape \[4, 3\], it must be \(n, 2\)"):
        pr.point(np.full((4, 3), 0.5, np.float32), 0.02)
    with pytest.raises(otbake.ArgumentError, match="points is not C-contiguous"):
        pr.point(np.full((2, 4), 0.5, np.float32).T, 0.02)
    with pytest.raises(otbake.ArgumentError, match="points must be a numpy array"):
        pr.point([[0.5, 0.5]], 0.02)
    with pytest.raises(otbake.QueryError, match=r"points\[1\]: a query coordinate is NaN"):
        pr.point(np.array([[0.5, 0.5], [np.nan, 0.5]], np.float32), 0.02)
    with pytest.raises(otbake.QueryError, match="kernel: kernel sigma must be a positive"):
        pr.point(P, -1.0)
    with pytest.raises(otbake.QueryError, match=r"indices\[1\]: sample index 99999 is out of range"):
        pr.sample(np.array([0, 99999], np.uint32))
    with pytest.raises(otbake.ArgumentError, match="indices has dtype int64, it must be uint32"):
        pr.sample(np.array([0, 1]))
    with pytest.raises(otbake.ArgumentError, match="hi has 3 rows but lo has 4"):
        pr.range(P, P[:3].copy())
    with pytest.raises(otbake.ArgumentError, match="res is"):
        pr.splat((16,), 0.02)
    with pytest.raises(otbake.ArgumentError, match="res is"):
        pr.point_grid((16, 0), 0.02)
    with pytest.raises(otbake.ArgumentError, match=r"start is \[16, 0\]"):
        pr.point_grid((16, 8), 0.02, start=(16, 0))
    with pytest.raises(otbake.ArgumentError, match=r"start is \[-1, 0\]"):
        pr.splat_region((16, 8), 0.02, start=(-1, 0))
    with pytest.raises(otbake.ArgumentError, match=r"size is \[4, 5\].*\[16, 4\]"):
        pr.splat_region((16, 8), 0.02, start=(0, 4), size=(4, 5))
    with pytest.raises(otbake.ArgumentError, match=r"size is \[0, 1\]"):
        pr.splat_region_rgba((16, 8), 0.02, size=(0, 1))
    with pytest.raises(otbake.QueryError, match="kernel: "):
        pr.point_grid((16, 8), float("nan"))
    with pytest.raises(otbake.QueryError, match="kernel: "):
        pr.splat_region((16, 8), 0.0)
