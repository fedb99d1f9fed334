"""The BSDF ``otbake_brdf``: a blend of BRDF maps as a Mitsuba BSDF.

``eval`` is the runtime's BRDF blend (``otbake.BrdfBlend.eval``: point queries of the blend in
the ``(θi, θo, φd)`` cube) times ``cos θo``. Mitsuba samples ``wo`` for a given ``wi``, while the
runtime's sampler draws the pair ``(wi, wo)`` jointly (``BrdfBlend.sample``), so the BSDF
samples from the blend's conditional in ``wi``'s θ band instead: for each of ``theta_bins``
bands of θi it tabulates ``f_Y(wi, wo) cos θo`` (runtime evaluations, the mean of 2×2 points per
cell) on ``theta_cells × phi_cells`` cells of ``(cos θo, φd)`` (rings of equal solid angle), picks a cell in proportion to its
integral, then a direction uniformly in solid angle inside it (``φd``'s sign with probability ½),
and mixes in a cosine-weighted lobe with probability ``cosine_fraction`` so that no direction where
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


class Tables:
    """The per-θi-band sampling tables of one BRDF blend and weights (pure numpy and runtime
    calls, no Mitsuba: the tests check it directly)."""

    def __init__(self, brdf, weights, theta_bins=16, theta_cells=32, phi_cells=32, cosine_fraction=0.1):
        self.brdf, self.weights = brdf, weights
        self.nb, self.nt, self.np_ = int(theta_bins), int(theta_cells), int(phi_cells)
        self.eps = float(cosine_fraction)
        if not (self.nb >= 1 and self.nt >= 1 and self.np_ >= 1 and 0.0 < self.eps <= 1.0):
            raise otbake.ArgumentError(
                "otbake_brdf: theta_bins, theta_cells and phi_cells must be >= 1 and 0 < cosine_fraction <= 1"
            )
        # Rings of equal solid angle: cos θo uniform in [0, 1] (first ring at the pole).
        self.cos_edges = 1.0 - np.arange(self.nt + 1) / self.nt
        self.dphi = np.pi / self.np_
        # Solid angle of one (θo, φd) cell on one side of the plane of incidence.
        self.area = np.repeat((self.cos_edges[:-1] - self.cos_edges[1:])[:, None], self.np_, axis=1) * self.dphi
        self.prob = {}
        self.cdf = {}

    def band(self, theta_i):
        return np.clip((theta_i / (np.pi / 2) * self.nb).astype(np.int64), 0, self.nb - 1)

    def table(self, b):
        if b not in self.prob:
            theta_i = (b + 0.5) * (np.pi / 2) / self.nb
            # 2×2 points per cell, equally spaced in cos θo and φd.
            sub = np.array([0.25, 0.75])
            ct = self.cos_edges[:-1, None] - sub[None, :] * (self.cos_edges[:-1] - self.cos_edges[1:])[:, None]
            pd = (np.arange(self.np_)[:, None] + sub[None, :]) * self.dphi
            to = np.arccos(np.clip(ct, 0.0, 1.0))  # (nt, 2)
            T, P = np.meshgrid(to.ravel(), pd.ravel(), indexing="ij")  # (2nt, 2np)
            wo = _direction(T.ravel(), P.ravel())
            wi = np.repeat(_direction(np.array([theta_i]), np.array([0.0])), len(wo), axis=0)
            f = self.brdf.eval(self.weights, wi, wo).astype(np.float64) @ LUMINANCE
            v = np.clip(f * wo[:, 2], 0.0, None).reshape(self.nt, 2, self.np_, 2).mean(axis=(1, 3))
            mass = v * self.area
            total = mass.sum()
            p = (mass / total).ravel() if total > 0 else np.zeros(self.nt * self.np_)
            self.prob[b] = p
            self.cdf[b] = np.cumsum(p)
        return self.prob[b], self.cdf[b]

    def pdf(self, wi, wo):
        """Density of :meth:`sample` in solid angle of ``wo`` for ``wi`` (both (n, 3), unit)."""
        theta_i = np.arccos(np.clip(wi[:, 2], -1.0, 1.0))
        bands = self.band(theta_i)
        phi_d = np.abs(np.angle(np.exp(1j * (np.arctan2(wo[:, 1], wo[:, 0]) - np.arctan2(wi[:, 1], wi[:, 0])))))
        t = np.clip(((1.0 - wo[:, 2]) * self.nt).astype(np.int64), 0, self.nt - 1)
        p = np.clip((phi_d / self.dphi).astype(np.int64), 0, self.np_ - 1)
        table = np.empty(len(wi))
        for b in np.unique(bands):
            sel = bands == b
            prob, _ = self.table(int(b))
            table[sel] = prob[t[sel] * self.np_ + p[sel]] / (2.0 * self.area[t[sel], p[sel]])
        dens = (1.0 - self.eps) * table + self.eps * np.clip(wo[:, 2], 0.0, None) / np.pi
        return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), dens, 0.0)

    def sample(self, wi, u1, u2):
        """Directions ``wo`` (n, 3) for ``wi`` from uniform ``u1`` (n,) and ``u2`` (n, 2)."""
        n = len(wi)
        wo = np.empty((n, 3))
        cos_lobe = u1 < self.eps
        # The cosine lobe.
        r = np.sqrt(u2[:, 0])
        phi = 2 * np.pi * u2[:, 1]
        lobe = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.clip(1 - u2[:, 0], 0, 1))], axis=1)
        wo[cos_lobe] = lobe[cos_lobe]
        # The tables.
        theta_i = np.arccos(np.clip(wi[:, 2], -1.0, 1.0))
        phi_i = np.arctan2(wi[:, 1], wi[:, 0])
        bands = self.band(theta_i)
        u = np.clip((u1 - self.eps) / (1.0 - self.eps) if self.eps < 1 else u1, 0.0, np.nextafter(1.0, 0))
        for b in np.unique(bands[~cos_lobe]):
            sel = (~cos_lobe) & (bands == b)
            prob, cdf = self.table(int(b))
            if cdf[-1] <= 0:
                wo[sel] = lobe[sel]
                continue
            cell = np.clip(np.searchsorted(cdf, u[sel] * cdf[-1], side="right"), 0, len(cdf) - 1)
            start = np.where(cell > 0, cdf[np.maximum(cell - 1, 0)], 0.0)
            frac = np.clip((u[sel] * cdf[-1] - start) / np.where(prob[cell] > 0, prob[cell], 1.0), 0.0, 1.0)
            t, p = cell // self.np_, cell % self.np_
            ct = self.cos_edges[t] - u2[sel, 0] * (self.cos_edges[t] - self.cos_edges[t + 1])
            pd = (p + u2[sel, 1]) * self.dphi
            phi_o = np.where(frac < 0.5, phi_i[sel] + pd, phi_i[sel] - pd)
            wo[sel] = _direction(np.arccos(np.clip(ct, 0.0, 1.0)), phi_o)
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
