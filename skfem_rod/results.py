"""Results of a solve: every converged step, queries at any arclength,
reactions, the load path, and export/render helpers."""
from dataclasses import dataclass, field

import numpy as np

from .element import shape_functions
from .kinematics import local_coordinates, strains


@dataclass
class Step:
    """One converged load step."""
    load_factor: float
    r: np.ndarray                  # (n_nodes, 3) nodal positions
    R: np.ndarray                  # (n_nodes, 3, 3) nodal rotations
    iterations: int
    residual_history: list
    energy: float                  # strain energy
    reactions: dict                # node -> (force (3,), moment (3,))
    external_work_rate: float = 0.0


class Result:
    """Converged load path of a rod.

    Attributes
    ----------
    steps : list of Step
        Step 0 is the reference (load factor 0).
    converged : bool
        True when the load factor 1 was reached.
    message : str
        How the solve ended (where and why it stopped, if it did).
    log : list of str
        Step cuts and other events along the way.
    """

    def __init__(self, rod):
        self.rod = rod
        self.steps = []
        self.converged = False
        self.message = "not solved"
        self.log = []

    # building ----------------------------------------------------------
    def append(self, lam, r, R, info):
        res = info.get("res")
        reactions = {}
        for n in self.rod.supports:
            if res is None:
                reactions[n] = (np.zeros(3), np.zeros(3))
            else:
                reactions[n] = (res[6 * n:6 * n + 3].copy(), res[6 * n + 3:6 * n + 6].copy())
        iw = info.get("iw")
        self.steps.append(Step(load_factor=float(lam), r=r.copy(), R=R.copy(),
                               iterations=int(info["iterations"]),
                               residual_history=list(info["history"]),
                               energy=float(iw.energy) if iw is not None else 0.0,
                               reactions=reactions))

    def finish(self, converged, message):
        self.converged = bool(converged)
        self.message = message

    def __repr__(self):
        return (f"Result(converged={self.converged}, steps={len(self.steps)}, "
                f"message={self.message!r})")

    # load path ---------------------------------------------------------
    @property
    def load_factors(self):
        return np.array([s.load_factor for s in self.steps])

    @property
    def iterations(self):
        return np.array([s.iterations for s in self.steps])

    @property
    def energies(self):
        return np.array([s.energy for s in self.steps])

    def reaction(self, where, step=-1):
        """(force, moment) the support at ``where`` exerts on the rod."""
        n = self.rod.node(where)
        return self.steps[step].reactions[n]

    # fields --------------------------------------------------------------
    def nodes(self, step=-1):
        """Nodal arclengths, positions and rotations ordered along the rod."""
        o = self.rod.mesh.order
        st = self.steps[step]
        return self.rod.mesh.s_nodes[o], st.r[o], st.R[o]

    def evaluate(self, s, step=-1):
        """Fields at arclengths ``s``: dict with ``r`` (n,3), ``R`` (n,3,3),
        strains ``v``, ``u`` and their reference values, and spatial stress
        resultants ``n``, ``m`` (n,3) (force and moment that the part beyond
        ``s`` exerts on the part before it)."""
        mesh, rod = self.rod.mesh, self.rod
        s = np.atleast_1d(np.asarray(s, dtype=float))
        e, xi = mesh.locate(s)
        h = mesh.vertices[e + 1] - mesh.vertices[e]
        N, dN, _ = shape_functions(xi)
        N, dN = N.T[:, None, :], (dN / h).T[:, None, :]        # (n, 1, 4)
        st = self.steps[step]
        nodes = mesh.nodes[e]

        def fields(r, R):
            loc = local_coordinates(r[nodes], R[nodes])
            psi = np.einsum("eqI,eIi->eqi", N, loc.psi)[:, 0]
            dpsi = np.einsum("eqI,eIi->eqi", dN, loc.psi)[:, 0]
            drho = np.einsum("eqI,eIi->eqi", dN, loc.rho)[:, 0]
            eps, Lam = strains(psi, dpsi, drho)
            return eps, loc.Rr @ Lam
        eps, Rs = fields(st.r, st.R)
        eps0, _ = fields(rod.r0, rod.R0)
        S = (eps - eps0) @ rod.C.T
        r = np.einsum("eqI,eIi->ei", N, st.r[nodes])
        return dict(s=s, r=r, R=Rs, v=eps[:, :3], u=eps[:, 3:], v0=eps0[:, :3],
                    u0=eps0[:, 3:], n=np.einsum("eij,ej->ei", Rs, S[:, :3]),
                    m=np.einsum("eij,ej->ei", Rs, S[:, 3:]))

    def position(self, s, step=-1):
        return self.evaluate(s, step)["r"]

    def frame(self, s, step=-1):
        return self.evaluate(s, step)["R"]

    def sample(self, per_element=8, step=-1):
        """Fields sampled uniformly along the rod (for output)."""
        n = self.rod.mesh.n_elements * per_element + 1
        return self.evaluate(np.linspace(0, self.rod.length, n), step)

    # output ------------------------------------------------------------------
    def point_data(self, step=-1, per_element=8):
        f = self.sample(per_element, step)
        return f, dict(arclength=f["s"], n=f["n"], m=f["m"], v=f["v"], u=f["u"],
                       twist=f["u"][:, 2] - f["u0"][:, 2])

    def write_vtu(self, path, step=-1, per_element=8):
        """Write one step as a VTU polyline with frames and resultants."""
        from .export import write_vtu
        f, pdata = self.point_data(step, per_element)
        return write_vtu(path, f["r"], f["R"], pdata)

    def write_series(self, directory, basename="rod", per_element=8):
        """Write every step (one VTU each) plus a time-series file."""
        from .export import write_series
        steps = []
        for k, st in enumerate(self.steps):
            f, pdata = self.point_data(k, per_element)
            steps.append(dict(time=st.load_factor, points=f["r"], frames=f["R"],
                              point_data=pdata))
        return write_series(directory, basename, steps)

    def render(self, filename, step=-1, radius=None, per_element=8, **kwargs):
        """Offscreen PNG of the rod as a tube with a stripe along ``d1``."""
        from .render import render_rod
        f = self.sample(per_element, step)
        if radius is None:
            radius = self.rod.section.radius or 0.01 * self.rod.length
        return render_rod(filename, f["r"], f["R"], radius, **kwargs)
