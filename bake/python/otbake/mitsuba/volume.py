"""The volume that serves a 3D blend's density to a ``heterogeneous`` medium: every lookup is a
runtime point query of the blend's mass (the values ``otbake volume`` writes into a ``.vol``, in
the inputs' units) at the lookup point mapped into the unit cube by ``to_world``'s inverse, as a
``gridvolume``'s grid is placed by its ``to_world``.

Mitsuba 3 has no plugin registry for Python volumes; build the object with :func:`volume` and
pass it as the medium's ``sigma_t`` (or ``albedo``) in ``mitsuba.load_dict``.
"""

import numpy as np

import otbake

from . import _common as c

#: A lookup grid with this many cells per kernel sigma finds the majorant (see ``max``).
_MAJORANT_CELLS_PER_SIGMA = 1.0
#: The majorant is the grid's largest value times this: between grid points at spacing sigma a
#: sum of Gaussians of width sigma can rise above its largest sample by at most exp(3/8) ≈ 1.45
#: for one Gaussian (half a cell diagonal in 3D is 0.87 sigma); 2 leaves room for overlaps. A
#: majorant too large costs tracking steps, never bias; one too small would bias the medium.
_MAJORANT_MARGIN = 2.0


def volume(manifest, weights, sigma, to_world=None):
    """A ``mitsuba.Volume`` of the blend of ``manifest``'s 3D inputs for ``weights`` (k numbers)
    under a Gaussian kernel ``sigma`` (unit-cube units, as ``otbake volume --sigma``), placed by
    ``to_world`` (a ``mitsuba.ScalarTransform4f``; default the unit cube [0, 1]³)."""
    mi = c.mi()
    blend = otbake.open_manifest(str(manifest))
    if blend.dim != 3:
        raise otbake.ArgumentError(
            f"otbake volume: the manifest's inputs are {blend.dim}-dimensional; the volume needs 3D inputs"
        )
    w = c.parse_weights(",".join(str(float(x)) for x in weights), blend.k, "otbake volume")
    blend.mean_mass(w)
    return _volume_class()(blend, w, float(sigma), to_world or mi.ScalarTransform4f())


_CLASSES = {}


def _volume_class():
    mi = c.mi()
    if mi.variant() in _CLASSES:
        return _CLASSES[mi.variant()]

    class BlendVolume(mi.Volume):
        def __init__(self, blend, weights, sigma, to_world):
            mi.Volume.__init__(self, mi.Properties())
            self.blend, self.weights, self.sigma = blend, weights, sigma
            self.to_world = to_world
            self.to_local = to_world.inverse()
            m = np.array(self.to_local.matrix, dtype=np.float64).reshape(4, 4)
            self.local = m
            self.majorant = self._majorant()

        def _majorant(self):
            res = int(np.ceil(_MAJORANT_CELLS_PER_SIGMA / self.sigma)) + 1
            g = (np.arange(res, dtype=np.float32) + 0.5) / res
            z, y, x = np.meshgrid(g, g, g, indexing="ij")
            pts = np.ascontiguousarray(np.stack([x, y, z], axis=-1).reshape(-1, 3))
            _, mass, _ = self.blend.point(self.weights, pts, self.sigma)
            return float(mass.max()) * _MAJORANT_MARGIN

        def _mass(self, it):
            p = c.vec3(it.p, np.float64)
            q = p @ self.local[:3, :3].T + self.local[:3, 3]
            _, mass, _ = self.blend.point(self.weights, q.astype(np.float32), self.sigma)
            return mass

        def eval_1(self, it, active=True):
            return c.to_float(self._mass(it))

        def eval(self, it, active=True):
            m = self._mass(it)
            return c.to_color(np.stack([m, m, m], axis=1))

        def eval_3(self, it, active=True):
            return c.to_vector(np.stack([self._mass(it)] * 3, axis=1))

        def max(self):
            return self.majorant

        def max_per_channel(self):
            return [self.majorant] * 3

        def bbox(self):
            return self.to_world @ mi.ScalarBoundingBox3f([0, 0, 0], [1, 1, 1])

        def resolution(self):
            return mi.ScalarVector3i(1, 1, 1)

        def to_string(self):
            return f"BlendVolume[k={self.blend.k}, sigma={self.sigma}]"

    _CLASSES[mi.variant()] = BlendVolume
    return BlendVolume
