"""The texture ``otbake_blend``: a 2D blend evaluated at the shading point's uv by runtime point
queries, and shaded by the maps' composite rule exactly as ``otbake blend`` shades a pixel (so a
``bitmap`` of ``otbake blend``'s EXR is the same texture sampled at pixel centres).

Properties:

* ``manifest`` (string): the manifest of 2D inputs (baked on load when not current);
* ``weights``: ``"a,b,..."`` (one per input, summing to 1), or a texture giving them per point:
  for 2 inputs a mono texture ``t`` (weights ``1 - t, t``), for 3 inputs an RGB texture (its
  channels, normalized to sum 1);
* ``sigma`` (float): the kernel's standard deviation in uv units (``otbake blend --sigma S`` at
  ``WxH`` is ``S / max(W, H)``).

uv maps to the blend's domain as a bitmap maps it to its image: u along axis 0 (image columns),
v along axis 1 (image rows, the first row at v = 0).
"""

import numpy as np

import otbake

from . import _common as c


def register_texture():
    mi = c.mi()

    class BlendTexture(mi.Texture):
        def __init__(self, props):
            mi.Texture.__init__(self, props)
            self.blend = c.open_blend(props, "otbake_blend")
            if self.blend.dim != 2:
                raise otbake.ArgumentError(
                    f"otbake_blend: the manifest's inputs are {self.blend.dim}-dimensional; the texture needs 2D inputs"
                )
            self.sigma = float(c.prop(props, "sigma", required=True))
            self.k = self.blend.k
            w = c.prop(props, "weights", required=True)
            if isinstance(w, mi.Texture):
                if self.k not in (2, 3):
                    raise otbake.ArgumentError(
                        f"otbake_blend: a weight texture serves 2 or 3 inputs, the manifest has {self.k}: give fixed weights"
                    )
                self.weight_texture, self.weights = w, None
            else:
                self.weight_texture, self.weights = None, c.parse_weights(w, self.k, "otbake_blend")
                self.blend.mean_mass(self.weights)  # checked once, here
            self.composite = self.blend.composite

        def _weights(self, si, n):
            if self.weight_texture is None:
                return self.weights
            if self.k == 2:
                t = np.clip(c.arr(self.weight_texture.eval_1(si)), 0.0, 1.0).astype(np.float64)
                w = np.stack([1.0 - t, t], axis=1)
            else:
                rgb = self.weight_texture.eval(si)
                w = np.stack([c.arr(rgb[0]), c.arr(rgb[1]), c.arr(rgb[2])], axis=1).astype(np.float64)
                w = np.clip(w, 0.0, None)
                s = w.sum(axis=1, keepdims=True)
                w = np.where(s > 0, w / np.where(s > 0, s, 1.0), 1.0 / self.k)
            return np.ascontiguousarray(np.broadcast_to(w, (n, self.k)), dtype=np.float32)

        def _rgb(self, si):
            uv = np.ascontiguousarray(np.stack([c.arr(si.uv.x), c.arr(si.uv.y)], axis=1))
            _, mass, color = self.blend.point(self._weights(si, len(uv)), uv, self.sigma)
            return otbake.shade(self.composite, mass, color)[:, :3]

        def eval(self, si, active=True):
            return c.to_color(self._rgb(si))

        def eval_3(self, si, active=True):
            return self.eval(si, active)

        def eval_1(self, si, active=True):
            rgb = self._rgb(si)
            return c.to_float(rgb @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32))

        def mean(self):
            # The texture's mean over uv: the shaded image on a 64² grid of cell centres.
            g = (np.arange(64, dtype=np.float32) + 0.5) / 64
            uv = np.ascontiguousarray(np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2))
            w = self.weights if self.weights is not None else np.full(self.k, 1.0 / self.k, np.float32)
            _, mass, color = self.blend.point(w, uv, self.sigma)
            return float(otbake.shade(self.composite, mass, color)[:, :3].mean())

        def is_spatially_varying(self):
            return True

        def to_string(self):
            return f"BlendTexture[k={self.k}, sigma={self.sigma}]"

    mi.register_texture("otbake_blend", lambda props: BlendTexture(props))
    return BlendTexture
