"""The implicit function of a domain bounded by labelled contour surfaces: the CSG of one implicit per surface,
closed by the base, and which surface gives f where."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from ...errors import check_number, check_points
from ...implicit.samples import contour_gap
from ...mesh.topology import boundary_facets
from .cardiac import BIVME_DEFAULT_DOMAIN, BIVME_SURFACES, EPICARDIAL_TAGS, LV_DOMAIN
from .csg import evaluate_domain

#: the name the base takes among the surfaces (in :meth:`LabelledImplicit.active_surface`).
BASE = "BASE"
#: the rim of the cavities' openings reaches this many thinnest walls below the base: a cavity's fit may run
#: through the epicardium's there (where the contours end short of the base), and a handle's cut may notch it
#: (:meth:`LabelledImplicit.data_surface`).
BASE_RIM = 2.0
#: below the rim a cavity is closed off by the thinnest wall wherever its fit runs beyond the epicardium's by up to
#: this many times its depth below the rim: 1 mm below it, 10 mm (the most measured on biv-me patient1's cine: 7 mm).
CLOSING = 10.0


@dataclass(frozen=True, eq=False)
class LabelledImplicit:
    """The domain's f: the CSG of one implicit per surface, closed by the base; callable (m, 3) -> (m,).

    Attributes
    ----------
    surfaces : name -> callable implicit (f > 0 inside), the surfaces the domain uses
    tree : the parsed domain (see :func:`~bitemesh.core.sources.contours.csg.parse_domain`); expression : its text
    base : the :class:`~bitemesh.core.sources.contours.base.BaseSurface` that closes the domain, or None
    min_wall : float, input units, the thinnest wall a difference keeps (see
        :func:`~bitemesh.core.sources.contours.csg.evaluate_domain`)
    lower, upper : (3,) float64, a box holding the domain (every point with f > 0)
    points : name -> (n, 3) distinct points of each surface; normals : name -> (n, 3) their in-plane normals (NaN
        where none); slices : name -> (n,) their slice ids
    derived : names of the surfaces built from others, not fitted to contours (an RV epicardium grown from the
        RV endocardium); shifts : slice id -> (3,) the in-plane shift each slice was moved by
        (:mod:`~bitemesh.core.sources.contours.registration`; ``points`` are the moved ones); disagreement : how far the
        contours still disagree where the slices cross once moved (input units, median); basal_slice : (point (3,),
        unit normal (3,) towards the base) of the short-axis stack's basal slice, or () without a stack or a base:
        beyond it the surfaces run on to the base where no short-axis contour samples them; notes : what was read,
        derived or chosen, one sentence each
    """

    surfaces: dict
    tree: tuple
    expression: str
    base: object
    min_wall: float
    lower: np.ndarray
    upper: np.ndarray
    points: dict
    normals: dict
    slices: dict = field(default_factory=dict)
    derived: tuple = ()
    shifts: dict = field(default_factory=dict)
    disagreement: float = 0.0
    basal_slice: tuple = ()
    notes: tuple = ()

    @property
    def is_myocardium(self) -> bool:
        """Whether the domain is a biv-me heart's myocardium (both ventricles, or the LV): with a base, a ball, its
        cavities open through it alone (a cavity's fit crossing the epicardium below it is closed by a wall, see
        :func:`~bitemesh.core.sources.contours.csg.evaluate_domain`; handles = "auto" removes the handles of its
        mesh and fills its voids); without one, its cavities are closed voids."""
        return (set(self.surfaces) <= set(BIVME_SURFACES) | set(self.derived)
                and self.expression in (BIVME_DEFAULT_DOMAIN, LV_DOMAIN))

    @property
    def rim(self) -> float:
        """How far below the base (input units) the rim of the cavities' openings reaches: :data:`BASE_RIM` x
        min_wall."""
        return BASE_RIM * self.min_wall

    @property
    def names(self) -> tuple:
        """The surface names, then :data:`BASE`: the values of :meth:`active_surface`."""
        return (*self.surfaces, BASE)

    def _evaluate(self, x):
        x = check_points(x, "x", dims=(3,))
        below = None if self.base is None else self.base.below(x)
        closed = 0.0 if below is None or not self.is_myocardium else \
            np.maximum(below - self.rim, 0) * CLOSING
        value, source = evaluate_domain(self.tree, {name: function(x) for name, function in self.surfaces.items()},
                                        self.min_wall, closed)
        if below is not None:
            cut = below < value
            value, source = np.where(cut, below, value), np.where(cut, len(self.surfaces), source)
        return value, source

    def __call__(self, x) -> np.ndarray:
        """(m,) f at (m, 3) points, > 0 inside the domain."""
        return self._evaluate(x)[0]

    def active_surface(self, x) -> np.ndarray:
        """(m,) index into :attr:`names` of the surface (or the base) whose implicit gives f at each point."""
        return self._evaluate(x)[1]

    def data_surface(self, x) -> np.ndarray:
        """(m,) index into :attr:`surfaces` of the surface whose implicit gives f at (m, 3) points, the epicardium's
        parts (LV_EPI and RV_EPI, one EPI on the mesh) counted as its first; -1 where the base does or within
        :attr:`rim` below it (the rim of the cavities' openings: a notch there is part of them)."""
        index = self.active_surface(x)
        rim = index == len(self.surfaces)
        if self.base is not None:
            rim |= self.base.below(x) < self.rim
        epicardium = [number for number, name in enumerate(self.surfaces) if name in EPICARDIAL_TAGS]
        if epicardium:
            index = np.where(np.isin(index, epicardium), epicardium[0], index)
        return np.where(rim, -1, index)

    def with_min_wall(self, min_wall: float) -> LabelledImplicit:
        """The same surfaces, with another thinnest wall (input units)."""
        return replace(self, min_wall=check_number(min_wall, "min_wall", low=0))

    def mapped(self, scale: float, shift) -> LabelledImplicit:
        """The same domain in the coordinates x * ``scale`` + ``shift`` (3,): every sampled surface (f scaled with
        the lengths, about a distance still), the base, the thinnest wall, the box, the points, the slices' shifts."""
        shift, scale = np.asarray(shift, dtype=np.float64), float(scale)
        return replace(self, surfaces={name: grid.scaled(grid.origin * scale + shift, scale)
                                       for name, grid in self.surfaces.items()},
                       base=None if self.base is None else self.base.mapped(scale, shift),
                       min_wall=self.min_wall * scale, lower=self.lower * scale + shift,
                       upper=self.upper * scale + shift,
                       points={name: points * scale + shift for name, points in self.points.items()},
                       shifts={number: moved * scale for number, moved in self.shifts.items()},
                       disagreement=self.disagreement * scale,
                       basal_slice=(self.basal_slice[0] * scale + shift, self.basal_slice[1]) if self.basal_slice
                       else ())

    def _kept(self) -> np.ndarray:
        """(n,) bool over the points of every surface in turn: those below the base (those above it are cut away)."""
        samples = np.vstack(list(self.points.values()))
        return np.ones(len(samples), bool) if self.base is None else self.base.below(samples) >= 0

    def surface_samples(self) -> np.ndarray:
        """(n, 3) the points of every surface that lie below the base (those above it are cut away)."""
        return np.vstack(list(self.points.values()))[self._kept()]

    def locate(self, indices) -> str:
        """Where the :meth:`surface_samples` of ``indices`` lie, as a sentence with a hint: the slice that holds
        most of them when one does (and its tilt to the short-axis stack when it is neither parallel nor
        perpendicular to it); "" when they are spread over the slices."""
        kept = self._kept()
        names = np.concatenate([[name] * len(points) for name, points in self.points.items()])[kept][indices]
        slices = np.concatenate([self.slices.get(name, np.full(len(points), -1))
                                 for name, points in self.points.items()])[kept][indices]
        if not len(slices):
            return ""
        numbers, counts = np.unique(slices, return_counts=True)
        number = int(numbers[np.argmax(counts)])
        if number < 0 or counts.max() < 0.5 * len(slices):
            return ""
        mine = np.concatenate([points[self.slices[name] == number] for name, points in self.points.items()
                               if name in self.slices])
        tilt = ""
        if self.base is not None and len(mine) >= 3:
            normal = np.linalg.svd(mine - mine.mean(axis=0), full_matrices=False)[2][2]
            angle = float(np.degrees(np.arccos(min(1.0, abs(normal @ self.base.normal)))))
            tilt = f", a slice at {angle:.0f} degrees to the short-axis stack," if 10 < angle < 80 else ""
        surfaces = ", ".join(f"{name} {int(np.sum(names[slices == number] == name))}"
                             for name in dict.fromkeys(names[slices == number].tolist()))
        return (f"{counts.max()} of those {len(slices)} points lie on slice {number} ({surfaces}){tilt} whose "
                "contours the other slices contradict: check that slice's position and orientation (the image "
                "header, its labels), or leave its rows out of the file")

    def contour_gap(self) -> float:
        """The gap the contours leave between their slices (:func:`bitemesh.core.implicit.samples.contour_gap`), the
        largest over the surfaces (input units)."""
        return max((contour_gap(points, self.slices[name]) for name, points in self.points.items()
                    if name in self.slices), default=0.0)

    def tracing_noise(self) -> float:
        """The uncertainty of traced contours (input units): half the median distance between neighbouring contour
        points (about the pixel size they were traced and resampled at), or the :attr:`disagreement` between the
        short- and long-axis contours when larger (no surface can pass nearer to both)."""
        spacing = [cKDTree(points).query(points, k=2)[0][:, 1] for points in self.points.values() if len(points) > 1]
        return max(0.5 * float(np.median(np.concatenate(spacing))) if spacing else 0.0, self.disagreement)

    def is_base(self, x) -> np.ndarray:
        """(m,) True where the base, not a surface, gives f at (m, 3) points."""
        return self.active_surface(x) == len(self.surfaces)

    def is_unsampled(self, x) -> np.ndarray:
        """(m,) True where no contour gives f at (m, 3) points: the base, a :attr:`derived` surface, or a surface
        between the basal short-axis slice and the base (run on to the valve rings, which only the long-axis
        contours' upper ends and the valve points sample)."""
        unsampled = [len(self.surfaces)] + [list(self.surfaces).index(name) for name in self.derived]
        made = np.isin(self.active_surface(x), unsampled)
        if self.basal_slice:
            point, normal = self.basal_slice
            made |= (np.asarray(x, dtype=np.float64) - point) @ normal > 0
        return made



def boundary_surfaces(mesh, function: LabelledImplicit):
    """The boundary triangles of a mesh of ``function``'s domain, and the surface each lies on.

    Returns
    -------
    facets : (b, 3) int64, boundary triangles oriented out of the domain
    surface : (b,) int64, index into ``function.names`` (the surfaces, then "BASE") of the implicit active at each
        triangle's centroid
    """
    facets = boundary_facets(np.asarray(mesh.cells))
    return facets, function.active_surface(np.asarray(mesh.points)[facets].mean(axis=1))

