"""The BSDF ``otbake_brdf``: a blend of BRDF maps as a Mitsuba BSDF.

``eval`` is the runtime's BRDF blend (``otbake.BrdfBlend.eval``: point queries of the blend in
the ``(θi, θo, φd)`` cube) times ``cos θo``. Mitsuba samples ``wo`` for a given ``wi``, while the
runtime's sampler draws the pair ``(wi, wo)`` jointly (``BrdfBlend.sample``), so the BSDF
samples from the blend's conditional in ``wi``'s θ band instead: for each of ``theta_bins``
bands of θi it tabulates ``f_Y(wi, wo) cos θo`` (runtime evaluations) on the nodes of a
``theta_cells × phi_cells`` grid over ``(1 − cos θo, φd)``, samples the bilinear interpolation of
those values exactly (:class:`Tables`; ``φd``'s sign with probability ½), and mixes in a cosine-weighted lobe with probability ``cosine_fraction`` so that no direction where
the BRDF is positive has zero pdf. ``pdf`` is that mixture's density, exactly — and 0 where the
BRDF is 0, where Mitsuba counts a sample as failed — so sampling and pdf agree (Mitsuba's χ² test
checks it) and ``weight = eval / pdf`` is unbiased.

Properties: ``manifest`` (BRDF inputs), ``weights`` (``"a,b,..."``), optionally ``sigma`` (a
fixed kernel instead of the adaptive default), ``theta_bins`` (16), ``theta_cells`` (32),
``phi_cells`` (32), ``cosine_fraction`` (0.1).
"""

import numpy as np

import otbake

from . import _common as c

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def _unit(v):
    v = np.nan_to_num(v)
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return np.where(n > 0, v / np.where(n > 0, n, 1.0), np.array([0.0, 0.0, 1.0]))


def _rows(n, *arrays):
    """Arrays broadcast to n rows (Dr.Jit broadcasts a width-1 value, e.g. a fixed ``wi``)."""
    return [np.ascontiguousarray(np.broadcast_to(a, (n,) + a.shape[1:])) for a in arrays]


def _direction(theta, phi):
    s = np.sin(theta)
    return np.ascontiguousarray(np.stack([s * np.cos(phi), s * np.sin(phi), np.cos(theta)], axis=1))


def _linear(a, b, u):
    """Inverse CDF on [0, 1] of the density proportional to ``a (1 - t) + b t``."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = a - b
    safe = np.abs(d) > 1e-12 * np.maximum(a + b, 1e-300)
    root = np.sqrt(np.maximum(a * a * (1 - u) + b * b * u, 0.0))
    t = np.where(safe, (a - root) / np.where(safe, d, 1.0), u)
    return np.clip(t, 0.0, 1.0)


def _pick(mass, u):
    """Cell index by ``mass`` (rows of cell masses) and the remainder of ``u`` in [0, 1)."""
    cdf = np.cumsum(mass, axis=-1)
    total = cdf[..., -1]
    x = u * total
    cell = np.minimum((cdf <= x[..., None]).sum(axis=-1), mass.shape[-1] - 1)
    start = np.where(cell > 0, np.take_along_axis(cdf, np.maximum(cell - 1, 0)[..., None], -1)[..., 0], 0.0)
    m = np.take_along_axis(mass, cell[..., None], -1)[..., 0]
    return cell, np.clip((x - start) / np.where(m > 0, m, 1.0), 0.0, np.nextafter(1.0, 0))


class Tables:
    """The sampling densities of one BRDF blend and weights, one per θi band (numpy and runtime
    calls only, no Mitsuba: the tests check it directly).

    A band's density of ``wo`` is bilinear on a grid of nodes over ``x = 1 − cos θo`` and
    ``y = φd / π`` (so continuous: Mitsuba's χ² test integrates it cell by cell), with node values
    ``f_Y(wi, wo) cos θo`` from the runtime at the band's centre θi; in solid angle it is
    ``q(x, y) / 2π`` (``φd``'s two signs, ``dω = dx · π dy`` per sign). It is sampled exactly:
    ``x`` from its piecewise-linear marginal, then ``y`` from the piecewise-linear conditional.
    """

    def __init__(self, brdf, weights, theta_bins=16, theta_cells=32, phi_cells=32, cosine_fraction=0.1):
        self.brdf, self.weights = brdf, weights
        self.nb, self.nt, self.np_ = int(theta_bins), int(theta_cells), int(phi_cells)
        self.eps = float(cosine_fraction)
        if not (self.nb >= 1 and self.nt >= 1 and self.np_ >= 1 and 0.0 < self.eps <= 1.0):
            raise otbake.ArgumentError(
                "otbake_brdf: theta_bins, theta_cells and phi_cells must be >= 1 and 0 < cosine_fraction <= 1"
            )
        self.nodes = {}

    def band(self, theta_i):
        return np.clip((theta_i / (np.pi / 2) * self.nb).astype(np.int64), 0, self.nb - 1)

    def table(self, b):
        """Node values of band ``b``, normalized so the bilinear density integrates to 1 over
        the unit square (all zeros if the BRDF is 0 there)."""
        if b not in self.nodes:
            theta_i = (b + 0.5) * (np.pi / 2) / self.nb
            x = np.arange(self.nt + 1) / self.nt
            y = np.arange(self.np_ + 1) / self.np_
            X, Y = np.meshgrid(x, y, indexing="ij")
            wo = _direction(np.arccos(np.clip(1.0 - X.ravel(), 0.0, 1.0)), Y.ravel() * np.pi)
            wi = np.repeat(_direction(np.array([theta_i]), np.array([0.0])), len(wo), axis=0)
            f = self.brdf.eval(self.weights, wi, wo).astype(np.float64) @ LUMINANCE
            v = np.clip(f * wo[:, 2], 0.0, None).reshape(self.nt + 1, self.np_ + 1)
            total = (v[:-1, :-1] + v[1:, :-1] + v[:-1, 1:] + v[1:, 1:]).sum() / (4 * self.nt * self.np_)
            self.nodes[b] = v / total if total > 0 else np.zeros_like(v)
        return self.nodes[b]

    def _coords(self, wi, wo):
        x = np.clip(1.0 - wo[:, 2], 0.0, 1.0)
        phi_d = np.abs(np.angle(np.exp(1j * (np.arctan2(wo[:, 1], wo[:, 0]) - np.arctan2(wi[:, 1], wi[:, 0])))))
        return x, np.clip(phi_d / np.pi, 0.0, 1.0)

    def pdf(self, wi, wo):
        """Density of :meth:`sample` in solid angle of ``wo`` for ``wi`` (both (n, 3), unit)."""
        bands = self.band(np.arccos(np.clip(wi[:, 2], -1.0, 1.0)))
        x, y = self._coords(wi, wo)
        i = np.minimum((x * self.nt).astype(np.int64), self.nt - 1)
        j = np.minimum((y * self.np_).astype(np.int64), self.np_ - 1)
        tx, ty = x * self.nt - i, y * self.np_ - j
        q = np.zeros(len(wi))
        for b in np.unique(bands):
            sel = bands == b
            v = self.table(int(b))
            a, c = i[sel], j[sel]
            sx, sy = tx[sel], ty[sel]
            q[sel] = ((1 - sx) * (1 - sy) * v[a, c] + sx * (1 - sy) * v[a + 1, c]
                      + (1 - sx) * sy * v[a, c + 1] + sx * sy * v[a + 1, c + 1])
        dens = (1.0 - self.eps) * q / (2 * np.pi) + self.eps * np.clip(wo[:, 2], 0.0, None) / np.pi
        return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), dens, 0.0)

    def sample(self, wi, u1, u2):
        """Directions ``wo`` (n, 3) for ``wi`` from uniform ``u1`` (n,) and ``u2`` (n, 2)."""
        n = len(wi)
        cos_lobe = u1 < self.eps
        r = np.sqrt(u2[:, 0])
        phi = 2 * np.pi * u2[:, 1]
        wo = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.clip(1 - u2[:, 0], 0, 1))], axis=1)
        bands = self.band(np.arccos(np.clip(wi[:, 2], -1.0, 1.0)))
        phi_i = np.arctan2(wi[:, 1], wi[:, 0])
        sign_u = np.clip((u1 - self.eps) / (1.0 - self.eps) if self.eps < 1 else u1, 0.0, 1.0)
        for b in np.unique(bands[~cos_lobe]):
            sel = (~cos_lobe) & (bands == b)
            v = self.table(int(b))
            if not v.any():
                continue  # a zero table is never picked: the BRDF is 0 for this band, keep the lobe
            m = sel.sum()
            # x: the marginal's node values (trapezoid over y), piecewise linear in x.
            mx = (v[:, :-1] + v[:, 1:]).sum(axis=1) / 2
            i, rx = _pick(np.broadcast_to((mx[:-1] + mx[1:]) / 2, (m, self.nt)), u2[sel, 0])
            tx = _linear(mx[i], mx[i + 1], rx)
            # y given x: the row interpolated at x, piecewise linear in y.
            row = (1 - tx)[:, None] * v[i] + tx[:, None] * v[i + 1]
            j, ry = _pick((row[:, :-1] + row[:, 1:]) / 2, u2[sel, 1])
            ty = _linear(row[np.arange(m), j], row[np.arange(m), j + 1], ry)
            x = (i + tx) / self.nt
            phi_d = (j + ty) / self.np_ * np.pi
            phi_o = np.where(sign_u[sel] < 0.5, phi_i[sel] + phi_d, phi_i[sel] - phi_d)
            wo[sel] = _direction(np.arccos(np.clip(1.0 - x, 0.0, 1.0)), phi_o)
        return np.ascontiguousarray(wo)


def register_bsdf():
    mi = c.mi()
    import drjit as dr

    class BrdfBsdf(mi.BSDF):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            sigma = c.prop(props, "sigma")
            kernel = {} if sigma is None else {"sigma": float(sigma)}
            self.brdf = c.open_blend(props, "otbake_brdf", brdf=True, **kernel)
            self.weights = c.parse_weights(c.prop(props, "weights", required=True), self.brdf.k, "otbake_brdf")
            self.brdf.eval(self.weights, np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, 1.0]]))
            self.tables = Tables(
                self.brdf,
                self.weights,
                c.prop(props, "theta_bins", 16),
                c.prop(props, "theta_cells", 32),
                c.prop(props, "phi_cells", 32),
                c.prop(props, "cosine_fraction", 0.1),
            )
            flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
            self.m_components = [flags]
            self.m_flags = flags

        def _value(self, wi, wo):
            ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
            f = self.brdf.eval(self.weights, wi, wo).astype(np.float64)
            return np.where(ok[:, None], f * np.clip(wo[:, 2], 0, None)[:, None], 0.0)

        def _dirs(self, si, wo):
            wi, w = _unit(c.vec3(si.wi)), _unit(c.vec3(wo))
            return _rows(max(len(wi), len(w)), wi, w)

        def eval(self, ctx, si, wo, active=True):
            wi, w = self._dirs(si, wo)
            return c.to_color(self._value(wi, w).astype(np.float32))

        def _value_pdf(self, wi, wo):
            # Mitsuba's convention: a sample whose value is 0 is a failed sample, so the pdf is 0
            # wherever the BRDF is (there the kernel estimate has no point within reach).
            value = self._value(wi, wo)
            pdf = np.where(value.max(axis=1) > 0, self.tables.pdf(wi, wo), 0.0)
            return value, pdf

        def pdf(self, ctx, si, wo, active=True):
            wi, w = self._dirs(si, wo)
            return c.to_float(self._value_pdf(wi, w)[1].astype(np.float32))

        def eval_pdf(self, ctx, si, wo, active=True):
            wi, w = self._dirs(si, wo)
            value, pdf = self._value_pdf(wi, w)
            return c.to_color(value.astype(np.float32)), c.to_float(pdf.astype(np.float32))

        def sample(self, ctx, si, sample1, sample2, active=True):
            wi = _unit(c.vec3(si.wi))
            u1 = c.arr(sample1, np.float64)
            u2 = np.stack([c.arr(sample2.x, np.float64), c.arr(sample2.y, np.float64)], axis=1)
            wi, u1, u2 = _rows(max(len(wi), len(u1), len(u2)), wi, u1, u2)
            wo = _unit(self.tables.sample(wi, u1, u2))
            value, pdf = self._value_pdf(wi, wo)
            weight = np.where(pdf[:, None] > 0, value / np.where(pdf > 0, pdf, 1.0)[:, None], 0.0)
            n = len(wi)
            if c.is_scalar():
                bs = mi.BSDFSample3f()
            else:
                bs = dr.zeros(mi.BSDFSample3f, n)
            bs.wo = c.to_vector(wo.astype(np.float32))
            bs.pdf = c.to_float(pdf.astype(np.float32))
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            bs.sampled_component = mi.UInt32(0)
            return bs, c.to_color(weight.astype(np.float32))

        def to_string(self):
            return f"BrdfBsdf[k={self.brdf.k}]"

    mi.register_bsdf("otbake_brdf", lambda props: BrdfBsdf(props))
    return BrdfBsdf
