"""Bad input: every error is a ValueError whose message names the parameter
(and, where it helps, what is allowed); a load step that cannot converge ends
the solve cleanly with every converged step kept."""
import re

import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry

BAD_POSITIVE = [0.0, -1.0, np.nan, np.inf, -np.inf, "abc", None]


def unit_section(**kw):
    args = dict(EA=100.0, GA1=50.0, GA2=50.0, EI1=1.0, EI2=1.0, GJ=0.8)
    args.update(kw)
    return Section(**args)


def cantilever(n_elements=4):
    return Rod(geometry.straight(1.0), unit_section(), n_elements).clamp("start")


# ------------------------------------------------------------------ geometry
@pytest.mark.parametrize("value", BAD_POSITIVE)
@pytest.mark.parametrize("make", [
    lambda L: geometry.straight(L),
    lambda L: geometry.curve(lambda s: np.c_[s, 0 * s, 0 * s], L),
], ids=["straight", "curve"])
def test_length_must_be_positive_and_finite(make, value):
    with pytest.raises(ValueError, match=r"length must be a finite number > 0"):
        make(value)


@pytest.mark.parametrize("value", BAD_POSITIVE)
@pytest.mark.parametrize("name, make", [
    ("radius", lambda v: geometry.arc(v, 1.0)),
    ("angle", lambda v: geometry.arc(1.0, v)),
    ("radius", lambda v: geometry.helix(v, 0.1, 1.0)),
    ("pitch", lambda v: geometry.helix(1.0, v, 1.0)),
    ("turns", lambda v: geometry.helix(1.0, 0.1, v)),
], ids=["arc-radius", "arc-angle", "helix-radius", "helix-pitch", "helix-turns"])
def test_shape_parameters_must_be_positive_and_finite(name, make, value):
    with pytest.raises(ValueError, match=rf"^{name} must be a finite number > 0, got"):
        make(value)


# ------------------------------------------------------------------- section
@pytest.mark.parametrize("value", BAD_POSITIVE)
def test_section_radius_must_be_positive_and_finite(value):
    if value is None:                       # None means "no radius": allowed
        assert unit_section(radius=None).radius is None
        return
    with pytest.raises(ValueError, match=r"^radius must be a (finite )?number > 0, got"):
        unit_section(radius=value)
    with pytest.raises(ValueError, match=r"^radius must be a (finite )?number > 0, got"):
        Section.circle(E=1e7, nu=0.3, radius=value)


@pytest.mark.parametrize("value", BAD_POSITIVE)
@pytest.mark.parametrize("name", ["EA", "GA1", "GA2", "EI1", "EI2", "GJ"])
def test_each_stiffness_must_be_positive_and_finite(name, value):
    with pytest.raises(ValueError, match=rf"^{name} must be a (finite )?number > 0, got"):
        unit_section(**{name: value})


@pytest.mark.parametrize("kw, name", [
    (dict(E=0.0), "E"), (dict(E=np.inf), "E"), (dict(nu=0.5), "nu"),
    (dict(nu=-1.0), "nu"), (dict(nu=np.nan), "nu"), (dict(nu="x"), "nu"),
])
def test_circle_material_parameters(kw, name):
    args = dict(E=1e7, nu=0.3, radius=0.01)
    args.update(kw)
    with pytest.raises(ValueError, match=rf"^{name} must"):
        Section.circle(**args)


def test_section_matrix_must_be_symmetric_positive_definite():
    C = np.diag([1.0, 1.0, 10.0, 1.0, 1.0, 1.0])
    C[0, 3] = 5.0                                 # not symmetric
    with pytest.raises(ValueError, match=r"^matrix must be symmetric"):
        Section.from_matrix(C)
    C[3, 0] = 5.0                                 # symmetric, indefinite
    with pytest.raises(ValueError, match=r"^matrix must be positive definite"):
        Section.from_matrix(C)
    with pytest.raises(ValueError, match=r"^matrix must be 6 x 6"):
        Section.from_matrix(np.eye(5))


# ---------------------------------------------------------------------- rod
@pytest.mark.parametrize("value", [0, -3, 2.5, 4.0, "4", None, True])
def test_n_elements_must_be_a_positive_integer(value):
    with pytest.raises(ValueError, match=r"^n_elements must be an integer >= 1, got"):
        Rod(geometry.straight(1.0), unit_section(), value)


def test_rod_rejects_wrong_shape_and_section_types():
    with pytest.raises(ValueError, match=r"^shape must be"):
        Rod("straight", unit_section(), 2)
    with pytest.raises(ValueError, match=r"^section must be"):
        Rod(geometry.straight(1.0), {"EA": 1.0}, 2)


@pytest.mark.parametrize("where", ["middle", 0.3, np.nan, None, [1.0], -1e-300, -0.25])
def test_where_must_be_an_end_or_a_node(where):
    with pytest.raises(ValueError, match=r"where"):
        cantilever().add_force(where, [1.0, 0.0, 0.0])


@pytest.mark.parametrize("components", [(3,), (-1,), (0, 5), (), (0.5,), (True,),
                                        (False, False, 0), (1, True)])
@pytest.mark.parametrize("method", ["pin", "fix_rotation", "prescribe_displacement"])
def test_support_components_must_be_axis_indices(method, components):
    rod = Rod(geometry.straight(1.0), unit_section(), 2)
    args = ([0.1, 0.0, 0.0],) if method == "prescribe_displacement" else ()
    with pytest.raises(ValueError, match=r"^components must be spatial axis indices"):
        getattr(rod, method)("end", *args, components=components)
    assert not rod.supports                  # nothing half-applied


# --------------------------------------------------------------------- loads
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("method, name", [
    ("add_force", "force"), ("add_moment", "moment"),
    ("add_distributed_force", "force"), ("add_distributed_torque", "torque"),
    ("prescribe_rotation", "rotation_vector"),
    ("prescribe_displacement", "displacement"),
])
def test_loads_must_be_finite(method, name, bad):
    rod = cantilever()
    vec = [0.0, bad, 1.0]
    call = getattr(rod, method)
    with pytest.raises(ValueError, match=rf"^{name} must be finite \(no NaN or inf\)"):
        if method.startswith("add_distributed"):
            call(vec)
        else:
            call("end", vec)
    assert not rod.point_loads and not rod.distributed
    assert list(rod.supports) == [rod.node("start")]     # nothing half-applied
    assert not rod.supports[rod.node("start")].rotation_vector.any()


@pytest.mark.parametrize("value, match", [
    ([1.0, 2.0], r"^force must be a 3-vector, got shape \(2,\)"),
    ("abc", r"^force must be a finite 3-vector of numbers"),
    (None, r"^force must be a 3-vector"),
])
def test_force_must_be_a_numeric_3_vector(value, match):
    with pytest.raises(ValueError, match=match):
        cantilever().add_force("end", value)


@pytest.mark.parametrize("method, name", [("add_distributed_force", "force"),
                                          ("add_distributed_torque", "torque")])
def test_distributed_load_callables_are_checked(method, name):
    rod = cantilever()
    with pytest.raises(ValueError, match=rf"^distributed {name} callable returned non-finite"):
        getattr(rod, method)(lambda s: np.where(s[:, None] > 0.5, np.nan, 1.0) * np.ones(3))
    with pytest.raises(ValueError, match=rf"^distributed {name} callable must return an "
                                         r"array of shape \(len\(s\), 3\)"):
        getattr(rod, method)(lambda s: np.ones((len(s), 2)))
    assert not rod.distributed
    getattr(rod, method)(lambda s: np.outer(s, [0.0, 0.0, 1e-3]))      # fine
    assert rod.solve(1).converged


# -------------------------------------------------------------------- solver
def test_unknown_solver_option_suggests_the_closest_name():
    with pytest.raises(ValueError, match=r"unknown solver option 'max_iteration'; "
                                         r"did you mean 'max_iterations'\?"):
        cantilever().solve(max_iteration=3)
    with pytest.raises(ValueError, match=r"unknown solver option 'line_serch'; "
                                         r"did you mean 'line_search'\?"):
        cantilever().solve(line_serch=False)


@pytest.mark.parametrize("kw, name", [
    (dict(rtol=-1.0), "rtol"), (dict(min_step=0.0), "min_step"),
    (dict(max_iterations=0), "max_iterations"), (dict(max_iterations=2.5), "max_iterations"),
    (dict(max_rotation_step=np.nan), "max_rotation_step"), (dict(grow=0.5), "grow"),
])
def test_bad_solver_option_values(kw, name):
    with pytest.raises(ValueError, match=rf"^{name} must be"):
        cantilever().solve(**kw)


@pytest.mark.parametrize("n_steps", [0, -1, 1.5, "2"])
def test_n_steps_must_be_a_positive_integer(n_steps):
    with pytest.raises(ValueError, match=r"^n_steps must be an integer >= 1"):
        cantilever().solve(n_steps)


def test_no_supports_names_all_six_rigid_body_modes():
    rod = Rod(geometry.straight(1.0), unit_section(), 2).add_force("end", [0, 1.0, 0])
    with pytest.raises(ValueError, match=r"rigid-body mode") as err:
        rod.solve()
    msg = str(err.value)
    assert msg.count("translation along") == 3
    assert msg.count("rotation about axis") == 3
    assert "Add a support" in msg


def _axes_in(msg):
    return [np.array([float(x) for x in m.split()])
            for m in re.findall(r"rotation about axis \[([^\]]*)\]", msg)]


@pytest.mark.parametrize("shape", [geometry.straight(1.0), geometry.arc(1.0, 2.0)],
                         ids=["straight", "arc"])
def test_pinned_at_both_ends_leaves_the_spin_about_the_chord(shape):
    rod = Rod(shape, unit_section(), 3).pin("start").pin("end")
    rod.add_force(shape.length / 3, [0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match=r"rigid-body mode") as err:
        rod.solve()
    msg = str(err.value)
    assert "translation" not in msg
    axes = _axes_in(msg)
    assert len(axes) == 1                       # the only free mode
    chord = rod.r0[rod.mesh.end_nodes[1]] - rod.r0[rod.mesh.end_nodes[0]]
    chord /= np.linalg.norm(chord)
    assert abs(abs(axes[0] @ chord) - 1) < 1e-3  # printed to 3 digits
    # fixing that spin at one end makes the problem well posed
    rod.fix_rotation("start", (0, 1, 2))
    assert rod.solve(1).converged


def test_load_step_that_cannot_converge_keeps_converged_steps():
    """A follower end moment of 4 turns on 2 elements: the local chart of an
    element admits < 0.95 pi rotation relative to its reference node, so
    load factors above ~0.36 have no admissible state; with
    max_iterations=3 the solve stops there, keeping the converged steps."""
    rod = Rod(geometry.straight(1.0), unit_section(GA1=100.0, GA2=100.0), 2)
    M = 8 * np.pi * 1.0                           # 4 turns: 8 pi EI / L
    rod.clamp("start").add_moment("end", [0.0, 0.0, M], follower=True)
    res = rod.solve(20, max_iterations=3, min_step=0.02)
    assert res.converged is False
    msg = res.message
    m = re.match(r"stopped at load factor ([0-9.e+-]+) \(pseudo-time [0-9.e+-]+\): the step "
                 r"to ([0-9.e+-]+) failed "
                 r"\((.+)\) and the step size fell below min_step=0.02", msg)
    assert m, msg
    lam_stop, lam_try, reason = float(m.group(1)), float(m.group(2)), m.group(3)
    assert reason                                    # says why
    lams = [st.load_factor for st in res.steps]
    assert lams[0] == 0.0 and len(lams) > 3           # converged steps are kept
    assert lams[-1] == pytest.approx(lam_stop) and lam_try > lam_stop
    assert all(b > a for a, b in zip(lams, lams[1:])) and max(lams) < 1
    assert res.log and all("failed" in line for line in res.log)
    for st in res.steps:
        assert np.all(np.isfinite(st.r)) and np.all(np.isfinite(st.R))
        assert np.isfinite(st.energy)
        assert np.all(np.isfinite(st.residual_history))
        for F, Mr in st.reactions.values():
            assert np.all(np.isfinite(F)) and np.all(np.isfinite(Mr))
        # kept steps are true equilibria: pure bending, energy M^2 L / (2 EI)
        assert st.energy == pytest.approx((st.load_factor * M) ** 2 / 2, rel=1e-8)
    assert np.all(np.isfinite(res.evaluate(np.linspace(0, 1, 7))["m"]))
