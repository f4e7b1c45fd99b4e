"""Regenerate the verification figures of docs/verification.md.

    /work/venv/bin/python docs/figures.py

writes ``docs/img/convergence.png`` (field-norm errors against the element
size, roll-up and cantilever) and ``docs/img/slenderness.png`` (tip error of
the tip-loaded cantilever against the slenderness for 3- and 4-point
integration) and prints the tables behind them.
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from skfem_rod import Rod, Section, analytic, geometry  # noqa: E402

IMG = Path(__file__).resolve().parent / "img"
L, EI = 1.0, 1.0


def gauss_points(rod, n=10):
    x, w = np.polynomial.legendre.leggauss(n)
    v = rod.mesh.vertices
    h = np.diff(v)[:, None]
    return (v[:-1, None] + h * (x + 1) / 2).ravel(), (h * w / 2).ravel()


def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    Q = np.zeros(a.shape + (3, 3))
    Q[..., 0, 0], Q[..., 0, 1], Q[..., 1, 0], Q[..., 1, 1] = c, -s, s, c
    Q[..., 2, 2] = 1.0
    return Q


def rotation_angle(Q):
    w = 0.5 * np.stack([Q[:, 2, 1] - Q[:, 1, 2], Q[:, 0, 2] - Q[:, 2, 0],
                        Q[:, 1, 0] - Q[:, 0, 1]], axis=1)
    return np.arctan2(np.linalg.norm(w, axis=1), 0.5 * (np.trace(Q, axis1=1, axis2=2) - 1))


def section(EA=1e4, GA=1e4):
    return Section(EA=EA, GA1=GA, GA2=GA, EI1=EI, EI2=EI, GJ=1.0)


# --------------------------------------------------------------------------
# convergence in field norms
# --------------------------------------------------------------------------
def rollup_errors(n_elements, phi=2 * np.pi):
    rod = Rod(geometry.straight(L), section(), n_elements)
    rod.clamp("start").add_moment("end", [0.0, 0.0, phi * EI / L])
    res = rod.solve(n_steps=4, rtol=1e-10)
    assert res.converged, res.message
    s, w = gauss_points(rod)
    f = res.evaluate(s)
    ex = analytic.rollup(L, EI, phi * EI / L, s)
    r_ex = np.c_[ex.x, ex.y, 0 * s]
    t_ex = np.c_[np.cos(ex.theta), np.sin(ex.theta), 0 * s]
    rp = np.einsum("nij,nj->ni", f["R"], f["v"])
    ang = rotation_angle(np.einsum("nji,njk->nik", f["R"], rot_z(ex.theta) @ rod.R0[0]))
    return (np.sqrt(w @ np.sum((f["r"] - r_ex) ** 2, 1)),
            np.sqrt(w @ np.sum((rp - t_ex) ** 2, 1)), np.sqrt(w @ ang**2))


def cantilever_errors(n_elements, alpha=5.0):
    ref = analytic.elastica_cantilever(alpha, EA=1e4, GA=1e4, EI=EI, length=L)
    rod = Rod(geometry.straight(L), section(), n_elements)
    rod.clamp("start").add_force("end", [0.0, alpha * EI / L**2, 0.0])
    res = rod.solve(n_steps=5, rtol=1e-10)
    assert res.converged, res.message
    s, w = gauss_points(rod)
    f = res.evaluate(s)
    theta = np.arctan2(f["R"][:, 1, 2], f["R"][:, 0, 2])
    return (np.sqrt(w @ ((f["r"][:, 0] - ref.x(s)) ** 2 + (f["r"][:, 1] - ref.y(s)) ** 2)),
            np.sqrt(w @ (theta - ref.theta(s)) ** 2))


def rate(n_el, err):
    return np.polyfit(np.log(L / np.asarray(n_el, float)), np.log(err), 1)[0]


def convergence_figure():
    n_el = np.array([2, 4, 8, 16, 32])
    h = L / n_el
    R = np.array([rollup_errors(n) for n in n_el])
    C = np.array([cantilever_errors(n) for n in n_el])
    series = [
        ("roll-up 2π, $L^2$ position", R[:, 0], "o-", True),
        ("roll-up 2π, $H^1$ seminorm ($r' = Rv$)", R[:, 1], "s-", True),
        ("cantilever $PL^2/EI=5$, $L^2$ position", C[:, 0], "^--", True),
        ("cantilever $PL^2/EI=5$, $L^2$ section angle", C[:, 1], "v--", True),
        ("roll-up 2π, $L^2$ rotation (exact: solver tolerance)", R[:, 2], "x:", False),
    ]
    print("Convergence (field norms), h = L / n_elements")
    print(f"{'n_el':>5} {'roll-up L2':>11} {'roll-up H1':>11} {'roll-up rot':>11} "
          f"{'cant. L2':>11} {'cant. angle':>11}")
    for k, n in enumerate(n_el):
        print(f"{n:5d} {R[k, 0]:11.3e} {R[k, 1]:11.3e} {R[k, 2]:11.1e} "
              f"{C[k, 0]:11.3e} {C[k, 1]:11.3e}")
    fig, ax = plt.subplots(figsize=(7.5, 7.0))
    for label, e, style, fit in series:
        if fit:
            p = rate(n_el, e)
            label = f"{label}: slope {p:.2f}"
            print(f"fitted rate  {label}")
        ax.loglog(h, e, style, label=label, ms=6)
    for p, c0 in ((4, R[0, 0]), (3, R[0, 1])):
        ax.loglog(h, c0 * 0.5 * (h / h[0]) ** p, color="0.6", lw=0.8)
        ax.annotate(f"$h^{p}$", (h[2], c0 * 0.5 * (h[2] / h[0]) ** p), color="0.4",
                    textcoords="offset points", xytext=(-14, -12))
    ax.set_xlabel("element size $h/L$")
    ax.set_ylabel("error (units of $L$, rad)")
    ax.set_title("P3 rod elements: convergence in field norms")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8.5, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=1,
              frameon=False)
    fig.tight_layout()
    fig.savefig(IMG / "convergence.png", dpi=130)
    plt.close(fig)


# --------------------------------------------------------------------------
# slenderness sweep
# --------------------------------------------------------------------------
def slender_tip_errors(ratio, n_quad, n_elements=8, alpha=2.0):
    """Tip error / L of the converged solution."""
    sec = Section.circle(E=1e7, nu=0.3, radius=L / ratio)
    ref = analytic.elastica_cantilever(alpha, EA=sec.EA, GA=sec.GA1, EI=sec.EI1, length=L)
    rod = Rod(geometry.straight(L), sec, n_elements, n_quad=n_quad)
    rod.clamp("start").add_force("end", [0.0, alpha * sec.EI1 / L**2, 0.0])
    res = rod.solve(n_steps=2, rtol=1e-10)
    assert res.converged, res.message
    end = rod.node("end")
    r = res.steps[-1].r
    return np.hypot(r[end, 0] - ref.x(L), r[end, 1] - ref.y(L)) / L


def slenderness_figure():
    ratios = np.array([10, 30, 100, 300, 1e3, 3e3, 1e4])
    E3 = np.array([slender_tip_errors(q, 3) for q in ratios])
    E4 = np.array([slender_tip_errors(q, 4) for q in ratios])
    E4_16 = np.array([slender_tip_errors(q, 4, n_elements=16) for q in ratios])
    print("\nSlenderness sweep: tip error / L, P L^2/EI = 2, Section.circle(E=1e7, nu=0.3)")
    print(f"{'L/radius':>9} {'3-pt':>10} {'4-pt':>10} {'4-pt 16 el.':>12}")
    for k, q in enumerate(ratios):
        print(f"{q:9g} {E3[k]:10.2e} {E4[k]:10.2e} {E4_16[k]:12.2e}")
    fig, ax = plt.subplots(figsize=(7.5, 6.5))
    ax.loglog(ratios, E3, "o-", label="3-point (default), 8 el.")
    ax.loglog(ratios, E4, "s-", color="C3", label="4-point (full), 8 el.")
    ax.loglog(ratios, E4_16, "s--", color="C1", label="4-point (full), 16 el.")
    ax.axhline(1e-6, color="0.5", lw=0.8, ls="--")
    ax.annotate("asserted bound 1e-6", (ratios[0], 1e-6), textcoords="offset points",
                xytext=(2, 4), color="0.4", fontsize=8)
    ax.set_xlabel("slenderness  length / radius")
    ax.set_ylabel("tip position error / L")
    ax.set_title("Tip-loaded cantilever ($PL^2/EI = 2$): locking of full integration")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8.5, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=1,
              frameon=False)
    fig.tight_layout()
    fig.savefig(IMG / "slenderness.png", dpi=130)
    plt.close(fig)


if __name__ == "__main__":
    IMG.mkdir(parents=True, exist_ok=True)
    convergence_figure()
    slenderness_figure()
    print(f"\nwrote {IMG / 'convergence.png'} and {IMG / 'slenderness.png'}")
