"""Shared test helpers: import a demo or benchmark script as a module,
check Coulomb's law on a solved result, spy on reports, find 2-cycles."""
import importlib.util
import pathlib

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEMOS = ROOT / "demos"


def _load(name, path):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def load_demo(name):
    """``demos/<name>.py`` imported as a module (demos are scripts, not a
    package)."""
    return _load(name, DEMOS / f"{name}.py")


def load_bench(name):
    """``benchmarks/<name>.py`` imported as a module: tests run a benchmark's
    own case (its rod, load path and measures) rather than a copy of it."""
    return _load(name, ROOT / "benchmarks" / f"{name}.py")


def coulomb_checks(result, gamma_T, gamma_R):
    """Coulomb's law at every converged step, for every active point."""
    for k, st in enumerate(result.steps[1:], start=1):
        c = st.contact
        assert c.friction
        # the state shown in renders: slip where a law with gamma > 0 slips
        shown = result.contact_states(k)
        assert shown.shape == c.state_T.shape
        for gamma, state in ((gamma_T, c.state_T), (gamma_R, c.state_R)):
            if gamma > 0:
                assert np.all(shown >= state)
        assert np.all((shown == 2) == (((c.state_T == 2) & (gamma_T > 0))
                                        | ((c.state_R == 2) & (gamma_R > 0))))
        assert np.all(c.force >= 0)
        for gamma, f, g, state in ((gamma_T, c.force_T, c.slip_T, c.state_T),
                                   (gamma_R, c.force_R, c.slip_R, c.state_R)):
            if gamma == 0:                   # that law is off: no force
                assert np.all(f == 0)
                continue
            # the bound |f| <= gamma f_N (to round-off)
            assert np.all(np.linalg.norm(f, axis=1) <= gamma * c.force * (1 + 1e-12) + 1e-300)
            slip = state == 2
            if slip.any():
                # at slipping points |f| = gamma f_N and f points along the slip
                assert np.allclose(np.linalg.norm(f[slip], axis=1), gamma * c.force[slip],
                                   rtol=1e-12)
                gn = np.linalg.norm(g[slip], axis=1)
                big = gn > 1e-3 * gn.max()
                cos = (np.sum(f[slip] * g[slip], axis=1)[big]
                       / (np.linalg.norm(f[slip], axis=1)[big] * gn[big]))
                assert cos.min() > 1 - 1e-5
        assert c.dissipation >= 0


def two_cycles(h, floor):
    """Indices ``k`` where the residuals ``h`` alternate with period 2
    above ``floor``: ``h[k] ~ h[k-2]`` and ``h[k-1] ~ h[k-3]`` (within 5 %),
    ``h[k]`` and ``h[k-1]`` apart by more than 20 % (a stagnating history is
    no cycle)."""
    h = np.asarray(h)
    return [k for k in range(3, h.size)
            if h[k] > floor and abs(h[k] / h[k - 2] - 1) < 0.05
            and abs(h[k - 1] / h[k - 3] - 1) < 0.05 and abs(h[k] / h[k - 1] - 1) > 0.2]


def spy_reports(monkeypatch, module, name):
    """Replace ``module.name`` (a solve returning ``(r, R, lam, report)``)
    by a wrapper that records every report; returns the list it fills."""
    seen = []
    orig = getattr(module, name)

    def spy(*a, **k):
        out = orig(*a, **k)
        seen.append(out[3])
        return out

    monkeypatch.setattr(module, name, spy)
    return seen


def bent_cantilever(tip_force=(0.0, 1.0, 0.0), n_elements=4):
    """A unit cantilever (EI = 1, GJ = 0.8, EA = GA = 1e4) clamped at its
    start, bent by a dead force at its end (load factor 1): a scene every
    solver option can run in a second."""
    from skfem_rod import Rod, Section, geometry
    rod = Rod(geometry.straight(1.0), Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0,
                                              GJ=0.8), n_elements)
    rod.clamp("start")
    rod.add_force("end", list(tip_force))
    return rod
