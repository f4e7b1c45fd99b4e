"""Issue 14: every public argument validated once, with an error naming the
parameter, the value and what is allowed (no raw traceback, no silent
coercion); conflicting supports, meaningless contact geometry, reference
shapes the mesh cannot represent and sizes beyond memory refused.  One test
per finding; each failed on the code before the fix."""
import re
import signal

import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry

SEC = Section.circle(E=1e7, nu=0.3, radius=0.01)
STIFF = dict(EA=1.0, GA1=1.0, GA2=1.0, EI1=1.0, EI2=1.0, GJ=1.0)


def cantilever(n=4):
    return Rod(geometry.straight(1.0), SEC, n).clamp("start")


@pytest.fixture(scope="module")
def solved():
    return cantilever().add_force("end", [0.0, 0.01, 0.0]).solve(1)


# --------------------------------------------------------------- booleans
@pytest.mark.parametrize("value", ["no", "yes", 0, 1, None, np.array([True])])
@pytest.mark.parametrize("method", ["add_force", "add_moment"])
def test_follower_must_be_a_bool(method, value):
    rod = cantilever()
    with pytest.raises(ValueError, match=r"^follower must be True or False, got"):
        getattr(rod, method)("end", [0.0, 1.0, 0.0], follower=value)
    assert not rod.point_loads


# ------------------------------------------------------- shape positions
@pytest.mark.parametrize("make, name", [
    (lambda v: geometry.straight(1.0, start=v), "start"),
    (lambda v: geometry.arc(1.0, 1.0, start=v), "start"),
    (lambda v: geometry.helix(1.0, 0.1, 1.0, axis_start=v), "axis_start"),
    (lambda v: geometry.ring(1.0, center=v), "center"),
])
@pytest.mark.parametrize("value", [[np.nan, 0, 0], [0, np.inf, 0], "abc", [1.0, 2.0]])
def test_shape_positions_are_checked(make, name, value):
    with pytest.raises(ValueError, match=rf"^{name} must be"):
        make(value)


@pytest.mark.parametrize("make, name", [
    (lambda: geometry.arc(1.0, 1.0, toward="ab"), "toward"),
    (lambda: geometry.arc(1.0, 1.0, toward=[1.0, 0.0, 0.0]), "toward"),
    (lambda: geometry.straight(1.0, direction=[0, 0, 0]), "direction"),
    (lambda: geometry.polyline("abc"), "points"),
    (lambda: geometry.polyline([[0, 0, 0], [1, np.nan, 0]]), "points"),
])
def test_shape_directions_and_points_name_the_parameter(make, name):
    with pytest.raises(ValueError, match=rf"^{name} must"):
        make()


def test_polyline_d1_needs_one_director_per_point():
    P = [[0, 0, 0], [1, 1, 0], [2, 0, 0]]
    with pytest.raises(ValueError, match=r"^d1 must have one row per point \(3\), got 2"):
        geometry.polyline(P, d1=[[0, 0, 1], [0, 0, 1]])
    with pytest.raises(ValueError, match=r"^d1 must be finite"):
        geometry.polyline(P, d1=[[0, 0, 1], [0, 0, np.nan], [0, 0, 1]])


def test_curve_d1_of_s_must_return_directors():
    shape = geometry.curve(lambda s: np.c_[s, 0 * s, 0 * s], 1.0, d1_of_s=lambda s: 1.0)
    with pytest.raises(ValueError, match=r"d1_of_s\(s\) must return finite directors"):
        Rod(shape, SEC, 4)


# ------------------------------------------------------------- results
def test_reaction_at_an_unsupported_node(solved):
    with pytest.raises(ValueError, match=r"^where='end': node \d+ \(s = 1\) has no "
                                         r"support.*supported nodes are at s = 0"):
        solved.reaction("end")


@pytest.mark.parametrize("call", [
    lambda r: r.position(1.0, step=99), lambda r: r.frame(1.0, step=-99),
    lambda r: r.reaction("start", step=5), lambda r: r.contact_points(step=5),
    lambda r: r.topology(step=7), lambda r: r.nodes(step=3),
    lambda r: r.position(1.0, step=1.5), lambda r: r.contact_states(step=2),
])
def test_step_index_out_of_range(solved, call):
    with pytest.raises(ValueError, match=r"^step"):
        call(solved)


@pytest.mark.parametrize("s", [False, True, "0.5", b"x", None, [True, 0.5], ["0.1"],
                               np.bool_(True), 1.5, -0.1, np.nan, [[0.5]]])
@pytest.mark.parametrize("field", ["position", "frame", "evaluate"])
def test_arclengths_are_numbers_on_the_rod(solved, field, s):
    """A bool is not an arclength (``False`` was read as 0, found by the
    fuzz); nor is a string, a NaN or a point off the rod."""
    with np.errstate(invalid="ignore"), pytest.raises(ValueError, match=r"^s must"):
        getattr(solved, field)(s)


@pytest.mark.parametrize("value", [0, -1, 2.5, "a", 10**9])
def test_sample_per_element(solved, value):
    with pytest.raises(ValueError, match=r"^per_element must be an integer"):
        solved.sample(value)


# -------------------------------------------------------------- section
def test_circle_out_of_range_blames_the_radius():
    with pytest.raises(ValueError, match=r"^radius=1e-90 with E=.*underflow"):
        Section.circle(E=1e7, nu=0.3, radius=1e-90)
    with pytest.raises(ValueError, match=r"^radius=1e\+100 with E=.*overflow"):
        Section.circle(E=1e7, nu=0.3, radius=1e100)


@pytest.mark.parametrize("call, name", [
    (lambda: Section.from_matrix("abc"), "matrix"),
    (lambda: Section(**dict(STIFF, matrix="abc")), "matrix"),
    (lambda: Section(**dict(STIFF, GJ=True)), "GJ"),
    (lambda: Section(**dict(STIFF, EA="2")), "EA"),
    (lambda: cantilever().support_basis("end", "abc"), "basis"),
])
def test_no_silent_coercion_and_the_parameter_named(call, name):
    with pytest.raises(ValueError, match=rf"^{name} must"):
        call()


def test_distributed_callable_errors_are_named():
    with pytest.raises(ValueError, match=r"^distributed force callable failed.*ZeroDivision"):
        cantilever().add_distributed_force(lambda s: 1 / 0)


# ------------------------------------------------------- extreme sizes
def test_huge_length_is_refused_not_called_a_rigid_body_mode():
    with pytest.raises(ValueError, match=r"^shape length 1e\+300 is out of the range"):
        Rod(geometry.straight(1e300), SEC, 4)
    with pytest.raises(ValueError, match=r"^shape length 1e-300 is out of the range"):
        Rod(geometry.straight(1e-300), SEC, 4)        # found by the fuzz: ZeroDivisionError
    # the rigid-body check is scale free: a clamped rod in any units is held
    for L in (1e-100, 1e100):
        Rod(geometry.straight(L), SEC, 4).clamp("start").check_constraints()
        Rod(geometry.arc(L, 1.0), SEC, 4).pin("start").pin("end").fix_rotation(
            "start", [0, 1]).check_constraints()


def test_sizes_beyond_memory_are_refused_with_the_limit():
    with pytest.raises(ValueError, match=r"^n_elements must be an integer in \[1, 2000000\], "
                                         r"got 1000000000000"):
        Rod(geometry.straight(1.0), SEC, 10**12)
    with pytest.raises(ValueError, match=r"^n_quad must be an integer in \[1, 32\]"):
        Rod(geometry.straight(1.0), SEC, 4, n_quad=10**9)
    with pytest.raises(ValueError, match=r"^n_steps must be an integer in \[1, 1000000\]"):
        cantilever().check_steps(10**9)
    from skfem_rod import validation
    with pytest.raises(ValueError, match=r"would need about .* GiB of memory, more than "
                                         r"the limit"):
        validation.memory_budget("a test", 2 * validation.MEMORY_LIMIT)


def test_solve_refuses_a_billion_steps_at_once():
    """Needs the solver to call ``rod.check_steps(n_steps)``."""
    def stop(*_):
        raise TimeoutError("solve(10**9) was not refused at once")
    old = signal.signal(signal.SIGALRM, stop)
    signal.alarm(30)
    try:
        with pytest.raises(ValueError, match=r"n_steps must be an integer in \[1, 1000000\]"):
            cantilever().add_force("end", [0.0, 0.01, 0.0]).solve(10**9)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


# ------------------------------------------------ conflicting supports
@pytest.mark.parametrize("first, second", [
    (lambda r: r.clamp("end"), lambda r: r.prescribe_displacement("end", [0.1, 0, 0])),
    (lambda r: r.prescribe_displacement("end", [0.1, 0, 0]), lambda r: r.clamp("end")),
    (lambda r: r.pin("end", [0]), lambda r: r.prescribe_displacement("end", [0.1, 0, 0], [0])),
    (lambda r: r.fix_rotation("end", [1]), lambda r: r.prescribe_rotation("end", [1.0, 0, 0])),
    (lambda r: r.prescribe_rotation("end", [1.0, 0, 0]), lambda r: r.clamp("end")),
    (lambda r: r.prescribe_rotation("end", [1.0, 0, 0]),
     lambda r: r.prescribe_rotation("end", [2.0, 0, 0])),
])
def test_conflicting_supports_are_refused(first, second):
    rod = cantilever()
    first(rod)
    before = {n: (s.position.copy(), s.rotation.copy(), s.displacement.copy(),
                  s.rotation_vector.copy()) for n, s in rod.supports.items()}
    with pytest.raises(ValueError, match=r"conflicts with .* prescribes its motion"):
        second(rod)
    for n, s in rod.supports.items():                    # nothing half-applied
        for a, b in zip(before[n], (s.position, s.rotation, s.displacement,
                                    s.rotation_vector)):
            np.testing.assert_array_equal(a, b)


def test_compatible_supports_still_combine():
    rod = cantilever()
    rod.pin("end").pin("end", [1]).fix_rotation("end", [0])       # holds only: fine
    rod2 = cantilever().prescribe_displacement("end", [0.1, 0, 0], [0]).pin("end", [1, 2])
    rod2.fix_rotation("end")
    assert rod2.solve(1).converged


# ------------------------------------------------------------- contact
def hairpin(gap, leg=0.5, n=60):
    """Polyline hairpin: legs along +x and back, ``gap`` apart (centrelines)."""
    a = gap / 2
    th = np.linspace(-np.pi / 2, np.pi / 2, 25)[1:-1]
    x = np.linspace(0.0, leg, n)
    P = np.vstack([np.c_[x, 0 * x, 0 * x], np.c_[leg + a * np.cos(th), a + a * np.sin(th),
                                                   0 * th], np.c_[x[::-1], gap + 0 * x, 0 * x]])
    return geometry.polyline(P)


@pytest.mark.parametrize("kw, match", [
    (dict(radius="0.01"), r"^radius must be a finite number > 0, got '0.01'"),
    (dict(penalty="1"), r"^penalty must be a finite number > 0"),
    (dict(exclusion=[0.1]), r"^exclusion must be a finite number > 0"),
    (dict(radius=0.6), r"^contact radius 0.6: the contact diameter 2 eps = 1.2 must be "
                       r"smaller than the rod"),
    (dict(exclusion=2.0), r"^contact exclusion 2 excludes every pair"),
    (dict(exclusion=0.01), r"^contact exclusion 0.01 must be at least the contact diameter"),
    (dict(penalty=1e300), r"^contact penalty 1e\+300 is out of range"),
    (dict(foo=1), r"^unknown contact option\(s\) 'foo'; allowed: radius, penalty"),
])
def test_contact_parameters_that_make_no_sense(kw, match):
    rod = cantilever(8)
    with pytest.raises(ValueError, match=match):
        rod.enable_contact(**kw)
    assert rod.contact is None


def test_contact_radius_making_strands_start_interpenetrated_names_where():
    shape = hairpin(0.03)                            # legs 0.03 apart
    rod = Rod(shape, Section.circle(1e7, 0.3, 0.01), 20).clamp("start").clamp("end")
    rod.enable_contact()                             # 2 eps = 0.02 < 0.03: fine
    with pytest.raises(ValueError, match=r"^contact radius 0.02: the strands start "
                                         r"interpenetrated: the reference centreline at "
                                         r"s = [\d.]+ and s = [\d.]+ is 0.0[23]\d* apart"):
        rod.enable_contact(radius=0.02)
    assert rod.contact.radius == 0.01                 # the previous options kept
    msg = ""
    try:
        rod.enable_contact(radius=0.02)
    except ValueError as err:
        msg = str(err)
    a, b = map(float, re.findall(r"s = ([\d.]+)", msg)[:2])
    r = shape(np.array([a, b]))[0]
    assert np.linalg.norm(r[0] - r[1]) < 0.038 and b - a >= np.pi * 0.02


def test_solve_checks_contact_set_after_the_fact():
    """check_constraints (called by every solve) re-checks the contact
    options, also when they were changed on rod.contact directly."""
    rod = cantilever(8).enable_contact()
    rod.contact.exclusion = 5.0
    with pytest.raises(ValueError, match=r"^contact exclusion 5 excludes every pair"):
        rod.check_constraints()


# ---------------------------------------------------- reference shapes
def test_reference_shape_the_mesh_cannot_represent():
    shape = geometry.arc(0.01, 100.0)                 # 16 turns on 4 elements
    with pytest.raises(ValueError, match=r"^the mesh cannot represent the reference shape") \
            as err:
        Rod(shape, SEC, 4)
    need = int(re.search(r"n_elements >= (\d+)", str(err.value)).group(1))
    rod = Rod(shape, SEC, need)                       # the advice is enough
    s = np.linspace(0, rod.length, 1001)
    res = rod.clamp("start").solve(1)
    assert np.abs(res.position(s) - shape(s)[0]).max() < 0.1 * 0.01


def test_coarse_helix_is_refused_with_the_element_count_not_load_steps():
    with pytest.raises(ValueError) as err:
        Rod(geometry.helix(0.1, 0.05, 10), SEC, 4)
    msg = str(err.value)
    assert "load step" not in msg and re.search(r"n_elements >= \d+", msg)


# ----------------------------------------------------------- file names
def test_nul_byte_in_output_names(solved, tmp_path):
    with pytest.raises(ValueError, match=r"^directory .* contains a NUL byte"):
        solved.write_series(str(tmp_path / "a\0b"), "rod")
    with pytest.raises(ValueError, match=r"^basename 'a\\x00b' is not allowed"):
        solved.write_series(tmp_path, "a\0b")
    with pytest.raises(ValueError, match=r"^path .* contains a NUL byte"):
        solved.write_vtu(str(tmp_path / "x\0.vtu"))
    assert not list(tmp_path.iterdir())


def test_polyline_points_nearly_coincident():
    """Found by the fuzz: points 1e-40 apart passed and made the spline
    ill-conditioned (rcond 1e-46)."""
    with pytest.raises(ValueError, match=r"^points must be distinct consecutive points: "
                                         r"points 0 and 1 are 1e-40 apart"):
        geometry.polyline([[0, 0, 0], [1e-40, 0, 0], [1, 1, 0]])


@pytest.mark.parametrize("nu", [False, True, "0.3", None])
def test_circle_nu_is_a_number(nu):
    """Found by the fuzz: nu=False was taken as 0."""
    with pytest.raises(ValueError, match=r"^nu must be a number in \(-1, 0.5\)"):
        Section.circle(E=1e7, nu=nu, radius=0.01)


def test_rod_beyond_the_memory_limit_is_refused_before_allocating(monkeypatch):
    from skfem_rod import validation
    monkeypatch.setattr(validation, "MEMORY_LIMIT", 2**30)
    with pytest.raises(ValueError, match=r"^a rod of n_elements=100000 \(n_quad=3\) would "
                                         r"need about 6.71 GiB of memory, more than the "
                                         r"limit of 1 GiB"):
        Rod(geometry.straight(1.0), SEC, 100_000)
    with pytest.raises(ValueError, match=r"keeping n_steps=1000000 steps of 13 nodes would "
                                         r"need about 1.16 GiB"):
        cantilever().check_steps(10**6)


@pytest.mark.parametrize("where", [True, False, np.bool_(True)])
def test_where_is_not_a_bool(where):
    """True was taken as the arclength 1 (the end of a unit rod)."""
    rod = cantilever()
    with pytest.raises(ValueError, match=r"^where must be 'start', 'end' or a nodal arclength"):
        rod.add_force(where, [0.0, 1.0, 0.0])
    assert not rod.point_loads


@pytest.mark.parametrize("value", [[True, 0, 0], np.array([True, False, False]),
                                   (0.0, 1.0, False)])
def test_vectors_of_bools_are_not_numbers(value):
    rod = cantilever()
    with pytest.raises(ValueError, match=r"^force must be a finite 3-vector of numbers"):
        rod.add_force("end", value)
    with pytest.raises(ValueError, match=r"^start must be a finite 3-vector of numbers"):
        geometry.straight(1.0, start=value)
