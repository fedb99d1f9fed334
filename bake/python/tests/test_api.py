"""The Python API against the Rust CLI and runtime: the same bits for the same queries."""

import struct

import numpy as np
import pytest

import otbake
from conftest import pixel_centres, read_exr, run

W4 = [0.2, 0.5, 0.3]


def test_bake_returns_the_report_as_a_dict(shapes):
    report = otbake.bake(shapes)
    names = [p["name"] for p in report["products"]]
    assert names.count("proxy") == 1 and {"duck", "heart", "tooth"} <= set(names)
    # Baked by the fixture already: nothing is rebuilt.
    assert all(p["status"] != "built" for p in report["products"]), report


def test_open_from_path_and_from_bytes_agree(shapes):
    proxy_path, maps = otbake.archives(shapes)
    a = otbake.Blend(otbake.Proxy.open(proxy_path), [otbake.Map.open(p) for _, p in maps])
    b = otbake.Blend(
        otbake.Proxy.open(open(proxy_path, "rb").read()),
        [otbake.Map.open(bytearray(open(p, "rb").read())) for _, p in maps],
    )
    pts = np.random.default_rng(1).random((500, 2), dtype=np.float32)
    for x, y in zip(a.point(W4, pts, 0.02), b.point(W4, pts, 0.02)):
        np.testing.assert_array_equal(x, y)
    assert (a.k, a.dim, a.n) == (3, 2, 1500)


def test_handles_keep_their_bytes_alive(shapes):
    proxy_path, maps = otbake.archives(shapes)
    data = [open(p, "rb").read() for _, p in maps]
    blend = otbake.Blend(otbake.Proxy.open(open(proxy_path, "rb").read()), [otbake.Map.open(d) for d in data])
    del data
    import gc

    gc.collect()
    d, _, _ = blend.point(W4, np.full((4, 2), 0.5, np.float32), 0.05)
    assert np.all(np.isfinite(d))


def test_point_queries_are_the_cli_image_bit_for_bit(shapes, otbake_bin, mi_scalar, work):
    out = work / "blend-q.exr"
    run(otbake_bin, "blend", shapes, "--weights", ",".join(map(str, W4)), "--size", "40x24", "--sigma", "0.75", "-o", out)
    cli = read_exr(mi_scalar, out)
    blend = otbake.open_manifest(shapes)
    _, mass, color = blend.point(np.array(W4, np.float32), pixel_centres(40, 24), np.float32(0.75) / np.float32(40))
    mine = otbake.shade(blend.composite, mass, color).reshape(24, 40, 4)
    np.testing.assert_array_equal(mine[..., : cli.shape[-1]], cli)


def test_splat_is_the_cli_splat_image_bit_for_bit(shapes, otbake_bin, mi_scalar, work):
    out = work / "blend-s.exr"
    run(otbake_bin, "blend", shapes, "--weights", ",".join(map(str, W4)), "--size", "48x32", "--method", "splat", "-o", out)
    cli = read_exr(mi_scalar, out)
    blend = otbake.open_manifest(shapes)
    density, color = blend.splat(W4, (48, 32), np.float32(0.5) / np.float32(48))
    assert density.shape == (32, 48) and color.shape == (32, 48, 3)
    mass = density * np.float32(blend.mean_mass(W4))
    mine = otbake.shade(blend.composite, mass, color)
    np.testing.assert_array_equal(mine[..., : cli.shape[-1]], cli)


def test_per_point_weights_equal_per_call_weights(shapes):
    blend = otbake.open_manifest(shapes)
    rng = np.random.default_rng(2)
    pts = rng.random((300, 2), dtype=np.float32)
    w = rng.dirichlet([1, 1, 1], size=300).astype(np.float32)
    w /= w.sum(axis=1, keepdims=True)
    d, m, c = blend.point(w, pts, 0.03)
    for i in (0, 17, 299):
        di, mi_, ci = blend.point(w[i], pts[i : i + 1], 0.03)
        assert (d[i], m[i]) == (di[0], mi_[0])
        np.testing.assert_array_equal(c[i], ci[0])


def test_range_sample_bandwidth_and_adaptive_queries(shapes):
    blend = otbake.open_manifest(shapes)
    n = blend.n
    count, mass, _ = blend.range(W4, np.zeros((1, 2), np.float32), np.ones((1, 2), np.float32))
    assert count[0] == n and mass[0] > 0
    pos, col = blend.sample(W4, np.arange(n, dtype=np.uint32))
    assert pos.shape == (n, 2) and col.shape == (n, 3)
    # Every sampled point lies in a tiny box around itself.
    lo, hi = pos[:50] - 1e-6, pos[:50] + 1e-6
    count, _, _ = blend.range(W4, np.ascontiguousarray(lo), np.ascontiguousarray(hi))
    assert np.all(count >= 1)
    bw = blend.bandwidth(W4, np.arange(10, dtype=np.uint32), 2.0, 0.001, 0.05)
    assert np.all((bw >= 0.001) & (bw <= 0.05))
    d, _, _ = blend.point_adaptive(W4, pos[:20].copy(), 2.0, 0.001, 0.05)
    assert np.all(d > 0)


def _read_vol(path):
    data = open(path, "rb").read()
    assert data[:3] == b"VOL" and data[3] == 3
    enc, x, y, z, ch = struct.unpack("<5i", data[4:24])
    assert enc == 1 and ch == 1
    return np.frombuffer(data[48:], dtype="<f4").reshape(z, y, x)


def test_point_grid_is_the_cli_volume_bit_for_bit(volumes, otbake_bin, work):
    out = work / "blend.vol"
    run(otbake_bin, "volume", volumes, "--weights", "0.4,0.6", "--res", "12", "--sigma", "0.03", "-o", out)
    vol = _read_vol(out)
    g = (np.arange(12, dtype=np.float32) + 0.5) / np.float32(12)
    z, y, x = np.meshgrid(g, g, g, indexing="ij")
    pts = np.ascontiguousarray(np.stack([x, y, z], axis=-1).reshape(-1, 3))
    _, mass, _ = otbake.open_manifest(volumes).point([0.4, 0.6], pts, 0.03)
    np.testing.assert_array_equal(mass.reshape(12, 12, 12), vol)


def brdf_n(manifest):
    return otbake.Proxy.open(otbake.archives(manifest)[0]).n


def test_brdf_samples_carry_their_eval_and_pdf(brdfs):
    brdf = otbake.open_manifest(brdfs, brdf=True)
    rng = np.random.default_rng(3)
    n = 400
    idx = rng.integers(0, brdf_n(brdfs), n).astype(np.uint32)
    xi = rng.random((n, 5))
    w = [0.3, 0.7]
    wi, wo, pdf, value = brdf.sample(w, idx, xi)
    ok = pdf > 0
    assert ok.mean() > 0.9
    np.testing.assert_allclose(brdf.eval(w, wi[ok], wo[ok]), value[ok], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(brdf.pdf(w, wi[ok], wo[ok]), pdf[ok], rtol=1e-5)
    # Below the horizon the BRDF is 0, and so is the pdf.
    down = np.array([[0.0, 0.0, -1.0]])
    assert brdf.eval(w, down, down)[0].tolist() == [0.0, 0.0, 0.0]
    assert brdf.pdf(w, down, down)[0] == 0.0


def test_brdf_joint_sampling_estimates_the_integral(brdfs):
    """E[f cos θo / pdf] over joint samples = ∫∫ f cos θo dωi dωo, integrated directly."""
    brdf = otbake.open_manifest(brdfs, brdf=True)
    w = [0.5, 0.5]
    rng = np.random.default_rng(4)
    n = 20000
    wi, wo, pdf, value = brdf.sample(w, rng.integers(0, brdf_n(brdfs), n).astype(np.uint32), rng.random((n, 5)))
    lum = value.astype(np.float64) @ [0.2126, 0.7152, 0.0722]
    est = np.where(pdf > 0, lum * wo[:, 2] / np.where(pdf > 0, pdf, 1), 0)
    # Direct: uniform directions on both hemispheres (pdf 1/(2π) each).
    def hemi(m):
        z = rng.random(m)
        phi = 2 * np.pi * rng.random(m)
        r = np.sqrt(1 - z * z)
        return np.ascontiguousarray(np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1))

    a, b = hemi(n), hemi(n)
    direct = (brdf.eval(w, a, b).astype(np.float64) @ [0.2126, 0.7152, 0.0722]) * b[:, 2] * (2 * np.pi) ** 2
    se = np.hypot(est.std() / np.sqrt(n), direct.std() / np.sqrt(n))
    assert abs(est.mean() - direct.mean()) < 4 * se, (est.mean(), direct.mean(), se)
