"""The contact search as it was before the bounded broad phase (commit
3a9ddde): every (slave, element) pair within reach from one k-d tree query,
then the capsule lower bounds and the pruned narrow phase.  Kept as the
reference the new search must reproduce (tests/test_contact_search.py);
quadratic in memory when elements are much shorter than the radius."""
import numpy as np
from scipy.spatial import cKDTree

from skfem_rod.contact.search import Pairs, _capsules, monomial_coefficients, _empty, _project


def search_dense(mesh, r, slaves, reach, exclusion):
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

    Notes
    -----
    The candidates (slave, master element) come from a k-d tree of element
    bounding spheres; each gets a lower bound of its distance, that to the
    element's chord capsule (:func:`_capsules`).  Per slave, the candidate
    with the smallest bound (preferring elements wholly outside ``I_s``) is
    projected first; then only candidates whose bound is below the closest
    admissible distance found so far are projected.  The answer is the same
    as projecting every candidate (a skipped candidate cannot be closer),
    at a cost per slave that does not grow under mesh refinement.
    """
    ne, ns = slaves.s.shape
    r_el = r[mesh.nodes]                                     # (ne, 4, 3)
    C = monomial_coefficients(r_el).transpose(1, 2, 0)               # (4, 3, ne)
    x = np.einsum("qI,eIc->eqc", slaves.N, r_el).reshape(-1, 3)
    s_sl = slaves.s.ravel()
    p0, p1, dev = _capsules(r_el)                            # sub-arc capsules
    # bounding spheres of the whole element curves (rigorous: whole chord
    # capsule, deviation bounded as for the sub-arcs)
    e0, e1, edev = _capsules(r_el, 1)
    centre = 0.5 * (e0[:, 0] + e1[:, 0])
    rad = 0.5 * np.linalg.norm(e1[:, 0] - e0[:, 0], axis=1) + edev[:, 0]
    tree_s, tree_c = cKDTree(x), cKDTree(centre)
    cand = tree_s.sparse_distance_matrix(tree_c, rad.max() + reach, output_type="ndarray")
    i, j = cand["i"].astype(np.int64), cand["j"].astype(np.int64)
    keep = cand["v"] <= rad[j] + reach
    # drop master elements that lie entirely inside the excluded arclength
    lo, hi = mesh.vertices[j], mesh.vertices[j + 1]
    si = s_sl[i]
    keep &= (lo <= si - exclusion) | (hi >= si + exclusion)
    i, j = i[keep], j[keep]
    # lower bound of the distance: to the nearest sub-arc capsule
    lb = np.full(i.size, np.inf)
    for q in range(p0.shape[1]):
        a0 = p0[j, q]
        xp = x[i] - a0
        cj = p1[j, q] - a0
        t = np.clip(np.einsum("ij,ij->i", xp, cj)
                    / np.maximum(np.einsum("ij,ij->i", cj, cj), 1e-300), 0.0, 1.0)
        lb = np.minimum(lb, np.linalg.norm(xp - t[:, None] * cj, axis=1) - dev[j, q])
    keep = lb < reach
    i, j, lb = i[keep], j[keep], lb[keep]
    if i.size == 0:
        return _empty(0)
    si = s_sl[i]
    outside = (mesh.vertices[j] >= si + exclusion) | (mesh.vertices[j + 1] <= si - exclusion)
    order = np.lexsort((lb, ~outside, i))
    first = order[np.r_[True, i[order][1:] != i[order][:-1]]]

    xT = np.ascontiguousarray(x.T)

    def narrow(k):
        jk = j[k]
        xi, interior, y = _project(xT[:, i[k]], C[:, :, jk])
        s_bar = mesh.vertices[jk] + xi * (mesh.vertices[jk + 1] - mesh.vertices[jk])
        dvec = (xT[:, i[k]] - y).T
        dist = np.linalg.norm(dvec, axis=1)
        ok = (np.abs(s_bar - s_sl[i[k]]) >= exclusion) & (dist < reach) & (dist > 0)
        return k[ok], xi[ok], interior[ok], s_bar[ok], dvec[ok], dist[ok]

    r1 = narrow(first)
    best = np.full(ne * ns, np.inf)
    best[i[r1[0]]] = r1[5]
    rest = np.ones(i.size, bool)
    rest[first] = False
    rest &= lb <= best[i] * (1.0 + 1e-10)
    second = np.flatnonzero(rest)
    n_cand = first.size + second.size
    r2 = narrow(second)
    k, xi, interior, s_bar, dvec, dist = (np.concatenate([u, v]) for u, v in zip(r1, r2))
    if k.size == 0:
        return _empty(n_cand)
    ik = i[k]
    order = np.lexsort((k, dist, ik))        # ties: first candidate, as a full pass would
    sel = order[np.r_[True, ik[order][1:] != ik[order][:-1]]]
    isel = ik[sel]
    return Pairs(slave=isel, s_elem=isel // ns, s_xi=slaves.xi[isel % ns], m_elem=j[k[sel]],
                 m_xi=xi[sel], s=s_sl[isel], s_bar=s_bar[sel], distance=dist[sel],
                 normal=dvec[sel] / dist[sel, None], interior=interior[sel],
                 weight=slaves.w.ravel()[isel], n_candidates=n_cand)


