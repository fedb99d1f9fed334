"""Prepared blends (`Blend.prepare`): the same bits as the blend's queries for the prepared
weights, region queries that agree with whole-grid ones and with the CLI, and the object's
ownership of its buffer and blend."""

import gc

import numpy as np

import otbake
from conftest import pixel_centres, run
from test_api import _read_vol

W = [0.2, 0.5, 0.3]


def _centres(res, start, size):
    """Cell centres of a region of a 2D grid, row by row (axis 0 fastest): (cells, 2) float32."""
    x = (np.arange(start[0], start[0] + size[0], dtype=np.float32) + 0.5) / np.float32(res[0])
    y = (np.arange(start[1], start[1] + size[1], dtype=np.float32) + 0.5) / np.float32(res[1])
    X, Y = np.meshgrid(x, y)
    return np.ascontiguousarray(np.stack([X, Y], axis=-1).reshape(-1, 2))


def test_prepared_queries_are_the_blends_bits(shapes):
    blend = otbake.open_manifest(shapes)
    pr = blend.prepare(W)
    assert (pr.dim, pr.n, pr.has_color, pr.wrap) == (blend.dim, blend.n, blend.has_color, blend.wrap)
    assert pr.weights == list(np.float32(W)) and pr.mean_mass == blend.mean_mass(W)
    rng = np.random.default_rng(11)
    pts = rng.random((700, 2), dtype=np.float32)
    for mine, theirs in zip(pr.point(pts, 0.03), blend.point(W, pts, 0.03)):
        np.testing.assert_array_equal(mine, theirs)
    lo = np.ascontiguousarray(pts[:200] - rng.random((200, 2), dtype=np.float32) * 0.3)
    hi = np.ascontiguousarray(pts[:200] + rng.random((200, 2), dtype=np.float32) * 0.3)
    for mine, theirs in zip(pr.range(lo, hi), blend.range(W, lo, hi)):
        np.testing.assert_array_equal(mine, theirs)
    idx = np.arange(blend.n, dtype=np.uint32)
    pos, col = pr.sample(idx)
    bpos, bcol = blend.sample(W, idx)
    np.testing.assert_array_equal(pos, bpos)
    np.testing.assert_array_equal(col, bcol)
    # The blended arrays are the samples (a clamped blend: no folding), in index order.
    np.testing.assert_array_equal(pr.positions, pos)
    np.testing.assert_array_equal(pr.colors, col)
    d, c = pr.splat((40, 24), 0.02)
    bd, bc = blend.splat(W, (40, 24), 0.02)
    assert d.shape == (24, 40) and c.shape == (24, 40, 3)
    np.testing.assert_array_equal(d, bd)
    np.testing.assert_array_equal(c, bc)
    d, c = pr.splat((40, 24), 0.02, color=False)
    assert c is None
    np.testing.assert_array_equal(d, bd)


def test_region_queries_agree_with_point_queries_and_the_whole_grid(shapes):
    blend = otbake.open_manifest(shapes)
    pr = blend.prepare(W)
    res, start, size, sigma = (24, 18), (5, 3), (13, 9), 0.04
    d, m, c = pr.point_grid(res, sigma, start=start, size=size)
    assert d.shape == (9, 13) and c.shape == (9, 13, 3)
    bd, bm, bc = blend.point(W, _centres(res, start, size), sigma)
    np.testing.assert_array_equal(d.reshape(-1), bd)
    np.testing.assert_array_equal(m.reshape(-1), bm)
    np.testing.assert_array_equal(c.reshape(-1, 3), bc)
    # The whole grid by default.
    d, _, _ = pr.point_grid((16, 12), sigma)
    np.testing.assert_array_equal(d.reshape(-1), pr.point(pixel_centres(16, 12), sigma)[0])
    # A band of rows and a box of cells of the splat are those cells of the whole splat.
    whole_d, whole_c = pr.splat(res, sigma)
    bd, bc = pr.splat_region(res, sigma, start=(0, 6), size=(24, 5))
    np.testing.assert_array_equal(bd, whole_d[6:11])
    np.testing.assert_array_equal(bc, whole_c[6:11])
    bd, bc = pr.splat_region(res, sigma, start=start, size=size)
    np.testing.assert_array_equal(bd, whole_d[3:12, 5:18])
    np.testing.assert_array_equal(bc, whole_c[3:12, 5:18])
    rgba = pr.splat_region_rgba(res, sigma, start=start, size=size)
    assert rgba.shape == (9, 13, 4)
    np.testing.assert_array_equal(rgba[..., :3], bc)
    np.testing.assert_array_equal(rgba[..., 3], bd)


def test_point_grid_is_the_cli_volume_bit_for_bit(volumes, otbake_bin, work):
    out = work / "prepared.vol"
    run(otbake_bin, "volume", volumes, "--weights", "0.4,0.6", "--res", "12", "--sigma", "0.03", "-o", out)
    _, mass, _ = otbake.open_manifest(volumes).prepare([0.4, 0.6]).point_grid((12, 12, 12), 0.03)
    assert mass.shape == (12, 12, 12)
    np.testing.assert_array_equal(mass, _read_vol(out))


def test_prepared_owns_its_buffer_and_keeps_its_blend(shapes):
    proxy_path, maps = otbake.archives(shapes)
    data = [open(p, "rb").read() for _, p in maps]
    blend = otbake.Blend(otbake.Proxy.open(open(proxy_path, "rb").read()), [otbake.Map.open(d) for d in data])
    pts = np.random.default_rng(3).random((50, 2), dtype=np.float32)
    want = blend.point(W, pts, 0.03)
    pr = blend.prepare(np.array(W, np.float32))
    other = blend.prepare([1.0, 0.0, 0.0])
    assert pr.blend is blend
    del blend, data
    gc.collect()
    for mine, theirs in zip(pr.point(pts, 0.03), want):
        np.testing.assert_array_equal(mine, theirs)
    # Two prepared blends of one blend hold their own buffers.
    assert not np.array_equal(other.positions, pr.positions)
    assert "weights=" in repr(pr)
