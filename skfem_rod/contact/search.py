r"""Contact search: slave points, broad phase, closest-point projection.

Slaves are the ``n_slave`` Gauss points of every element (the paper's
three, sec. 7.1).  Each slave ``s`` is projected on the rod outside its
excluded neighbourhood ``I_s`` (eq. 3.1):

    s_bar = argmin_{|sigma - s| >= exclusion} |r(s) - r(sigma)|.

*Exclusion length.*  Neighbouring points of a rod are always closer than
its diameter, so pairs with ``|sigma - s| < exclusion`` are never contacts.
For a rod whose radius of curvature never falls below its radius ``eps``,
the chord between two points ``Delta s`` apart is at least
``2 eps sin(Delta s / (2 eps))``, which first reaches the contact distance
``2 eps`` at ``Delta s = pi eps``: the default is ``exclusion = pi eps``.

*Broad phase.*  A k-d tree (``scipy.spatial.cKDTree``) of element bounding
spheres gives, for every slave, the master elements within reach: cost
``O(n log n)``, not ``O(n^2)``.

*Narrow phase.*  A safeguarded Newton projection of the slave point on each
candidate cubic element (parameter clamped to the element, started from
the best of five samples), all candidate pairs at once.  Per slave the
closest admissible projection is kept; a projection that lands on the
exclusion boundary is not a contact and is dropped.
"""
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..element import shape_functions


@dataclass
class Slaves:
    """Slave points: ``n_slave`` Gauss points per element."""
    xi: np.ndarray        # (ns,) reference coordinates in an element
    N: np.ndarray         # (ns, 4) shape functions at xi
    s: np.ndarray         # (ne, ns) arclengths
    w: np.ndarray         # (ne, ns) integration weights (ds)


def slave_points(mesh, n_slave=3):
    """Gauss points used as contact slaves."""
    x, w = np.polynomial.legendre.leggauss(n_slave)
    xi, w = 0.5 * (x + 1), 0.5 * w
    h = np.diff(mesh.vertices)
    N, _, _ = shape_functions(xi)
    return Slaves(xi=xi, N=N.T, s=mesh.vertices[:-1, None] + h[:, None] * xi,
                  w=h[:, None] * w)


@dataclass
class Pairs:
    """Closest-point pairs, one per slave in contact range."""
    slave: np.ndarray     # (m,) global slave index  e * ns + q
    s_elem: np.ndarray    # (m,) slave element
    s_xi: np.ndarray      # (m,) slave reference coordinate
    m_elem: np.ndarray    # (m,) master element
    m_xi: np.ndarray      # (m,) master reference coordinate
    s: np.ndarray         # (m,) slave arclength
    s_bar: np.ndarray     # (m,) master arclength
    distance: np.ndarray  # (m,) |r(s) - r(s_bar)|
    normal: np.ndarray    # (m, 3) N = (r(s) - r(s_bar)) / distance
    interior: np.ndarray  # (m,) projection inside the element (stationary)
    weight: np.ndarray    # (m,) quadrature weight (ds) of the slave point
    n_candidates: int = 0 # narrow-phase candidate pairs tested

    @property
    def size(self):
        return self.slave.size


def _curve(r_el, xi):
    """Positions and first/second xi-derivatives of element curves."""
    Nall = np.stack(shape_functions(xi), axis=-1)    # (4, m, 3): N, dN, d2N
    Y = np.swapaxes(Nall, 0, 1).transpose(0, 2, 1) @ r_el   # (m, 3, 3)
    return Y[:, 0], Y[:, 1], Y[:, 2]


def project(x, r_el, iterations=12):
    """Closest points on cubic curves ``r_el`` ``(m, 4, 3)`` (scikit-fem
    local node order) to points ``x`` ``(m, 3)``, parameter in [0, 1].

    Returns ``xi`` (m,) and a flag ``interior`` (stationary point strictly
    inside the element)."""
    m = x.shape[0]
    samples = np.linspace(0.0, 1.0, 5)
    d2 = np.stack([np.sum((_curve(r_el, np.full(m, t))[0] - x) ** 2, axis=1)
                   for t in samples])
    xi = samples[np.argmin(d2, axis=0)]
    todo = np.arange(m)
    for _ in range(iterations):
        y, y1, y2 = _curve(r_el[todo], xi[todo])
        xt = x[todo]
        f = np.sum((y - xt) * y1, axis=1)
        fp = np.sum(y1 * y1, axis=1) + np.sum((y - xt) * y2, axis=1)
        # Newton where the distance is locally convex, a gradient step else
        step = np.where(fp > 1e-12 * np.sum(y1 * y1, axis=1), f / np.where(fp == 0, 1, fp),
                        0.25 * np.sign(f))
        new = np.clip(xi[todo] - step, 0.0, 1.0)
        moved = np.abs(new - xi[todo]) > 1e-15
        xi[todo] = new
        todo = todo[moved]
        if todo.size == 0:
            break
    y, y1, _ = _curve(r_el, xi)
    f = np.abs(np.sum((y - x) * y1, axis=1))
    interior = (xi > 0.0) & (xi < 1.0) & (f <= 1e-9 * (np.linalg.norm(y1, axis=1)
                                                          * np.linalg.norm(y - x, axis=1) + 1e-300))
    return xi, interior


def search(mesh, r, slaves, reach, exclusion):
    """All slave/master pairs with a centreline distance below ``reach``.

    Parameters
    ----------
    mesh : RodMesh
    r : (n_nodes, 3) nodal positions
    slaves : Slaves
    reach : float
        Largest centreline distance of interest (``2 eps`` plus a margin).
    exclusion : float
        Excluded arclength around each slave (see module docstring).
    """
    ne, ns = slaves.s.shape
    r_el = r[mesh.nodes]                                     # (ne, 4, 3)
    x = np.einsum("qI,eIc->eqc", slaves.N, r_el).reshape(-1, 3)
    s_sl = slaves.s.ravel()
    # bounding spheres of the element curves (sampled densely: cubic bulge)
    pts = _curve(np.repeat(r_el, 9, axis=0), np.tile(np.linspace(0, 1, 9), ne))[0]
    pts = pts.reshape(ne, 9, 3)
    centre = pts.mean(axis=1)
    rad = 1.05 * np.linalg.norm(pts - centre[:, None], axis=2).max(axis=1)
    tree_s, tree_c = cKDTree(x), cKDTree(centre)
    cand = tree_s.sparse_distance_matrix(tree_c, rad.max() + reach, output_type="ndarray")
    i, j = cand["i"].astype(np.int64), cand["j"].astype(np.int64)
    keep = cand["v"] <= rad[j] + reach
    # drop master elements that lie entirely inside the excluded arclength
    lo, hi = mesh.vertices[j], mesh.vertices[j + 1]
    keep &= (lo <= s_sl[i] - exclusion) | (hi >= s_sl[i] + exclusion)
    i, j = i[keep], j[keep]
    n_cand = i.size
    if n_cand == 0:
        return _empty(n_cand)
    xi, interior = project(x[i], r_el[j])
    h = mesh.vertices[j + 1] - mesh.vertices[j]
    s_bar = mesh.vertices[j] + xi * h
    y = _curve(r_el[j], xi)[0]
    dvec = x[i] - y
    dist = np.linalg.norm(dvec, axis=1)
    ok = (np.abs(s_bar - s_sl[i]) >= exclusion) & (dist < reach) & (dist > 0)
    # a minimum on the element end is a contact only if it is not the
    # exclusion boundary (those are rejected above) -- keep vertex minima
    i, j, xi, interior, s_bar, dvec, dist = (a[ok] for a in (i, j, xi, interior, s_bar, dvec, dist))
    if i.size == 0:
        return _empty(n_cand)
    order = np.lexsort((dist, i))
    first = np.r_[True, i[order][1:] != i[order][:-1]]
    k = order[first]
    i, j = i[k], j[k]
    return Pairs(slave=i, s_elem=i // ns, s_xi=slaves.xi[i % ns], m_elem=j, m_xi=xi[k],
                 s=s_sl[i], s_bar=s_bar[k], distance=dist[k],
                 normal=dvec[k] / dist[k, None], interior=interior[k],
                 weight=slaves.w.ravel()[i], n_candidates=n_cand)


def _empty(n_cand):
    z = np.zeros(0)
    zi = np.zeros(0, dtype=np.int64)
    return Pairs(slave=zi, s_elem=zi, s_xi=z, m_elem=zi, m_xi=z, s=z, s_bar=z,
                 distance=z, normal=np.zeros((0, 3)), interior=np.zeros(0, bool),
                 weight=z, n_candidates=n_cand)
