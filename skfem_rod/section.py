"""Cross-section stiffness of the rod.

The section stiffness ``C`` is the paper's 6 x 6 matrix ``A`` (eq. 5.2), in
the order of the material strains ``(v1, v2, v3, u1, u2, u3)``:
shear along ``d1``, ``d2``, stretch along ``d3``, bending about ``d1``,
``d2``, twist about ``d3``.  Diagonal: ``(GA1, GA2, EA, EI1, EI2, GJ)``.
"""
from dataclasses import dataclass

import numpy as np

import skfem_rod.validation as validation
from .validation import positive

_NAMES = ("GA1", "GA2", "EA", "EI1", "EI2", "GJ")


@dataclass(frozen=True, kw_only=True)
class Section:
    """Section stiffness (and radius, used by contact and rendering).

    Parameters
    ----------
    EA, GA1, GA2, EI1, EI2, GJ : float
        Axial, shear, bending and torsional stiffnesses (all > 0), by
        keyword only: ``Section(EA=..., GA1=..., GA2=..., EI1=..., EI2=...,
        GJ=...)`` (the stiffness matrix :attr:`C` orders them ``GA1, GA2,
        EA, EI1, EI2, GJ``, so a positional order would be a trap).
    radius : float, optional
        Radius of the circular cross-section (the paper's ``eps``).
    matrix : array (6, 6), optional
        A full symmetric positive-definite stiffness replacing the diagonal.

    Examples
    --------
    >>> sec = Section.circle(E=1e6, nu=0.3, radius=0.01)
    >>> round(sec.GJ / sec.EI1, 4)      # = 1 / (1 + nu) for a circle
    0.7692
    """
    EA: float
    GA1: float
    GA2: float
    EI1: float
    EI2: float
    GJ: float
    radius: float = None
    matrix: np.ndarray = None

    def __new__(cls, *args, **kwargs):
        if args:
            raise TypeError(
                f"Section takes its stiffnesses by keyword, got {len(args)} positional "
                "argument(s): write Section(EA=..., GA1=..., GA2=..., EI1=..., EI2=..., "
                "GJ=..., radius=...) (the matrix C orders them GA1, GA2, EA, EI1, EI2, "
                "GJ), or use Section.circle(E=..., nu=..., radius=...) or "
                "Section.from_matrix(C)")
        return super().__new__(cls)

    def __post_init__(self):
        for n in _NAMES:
            object.__setattr__(self, n, positive(n, getattr(self, n)))
        if self.radius is not None:
            object.__setattr__(self, "radius", positive("radius", self.radius))
        if self.matrix is not None:
            try:
                C = np.array(self.matrix, dtype=float)
            except (TypeError, ValueError, OverflowError):
                raise ValueError(f"matrix must be a finite 6 x 6 array, got "
                                 f"{self.matrix!r}") from None
            if C.shape != (6, 6) or not np.all(np.isfinite(C)):
                raise ValueError(f"matrix must be a finite 6 x 6 array, got shape {C.shape}")
            if not np.allclose(C, C.T, rtol=1e-12, atol=0):
                raise ValueError("matrix must be symmetric")
            if np.linalg.eigvalsh(C).min() <= 0:
                raise ValueError("matrix must be positive definite")
            object.__setattr__(self, "matrix", C)

    @classmethod
    def circle(cls, E, nu, radius, shear_coefficient=None):
        """Solid circular section of ``radius`` from Young's modulus ``E`` and
        Poisson's ratio ``nu`` (``-1 < nu < 0.5``).

        ``EA = E pi r^2``, ``EI1 = EI2 = E pi r^4 / 4``, ``GJ = G pi r^4 / 2``,
        ``GA1 = GA2 = k G A`` with ``G = E / 2(1 + nu)``.

        Parameters
        ----------
        E : float
            Young's modulus, > 0.
        nu : float
            Poisson's ratio, in ``(-1, 0.5)``.
        radius : float
            Radius, > 0; also the contact radius and the render radius.
        shear_coefficient : float, optional
            ``k``; default Cowper's ``6 (1 + nu) / (7 + 6 nu)``.

        Returns
        -------
        Section

        Examples
        --------
        >>> sec = Section.circle(E=2e11, nu=0.3, radius=1e-3)      # a 2 mm steel wire
        >>> round(sec.EI1, 6), round(sec.GA1 / (sec.EA / (2 * 1.3)), 4)
        (0.15708, 0.8864)
        """
        E = positive("E", E)
        radius = positive("radius", radius)
        try:
            nu_f = float(nu) if validation._is_real(nu) else np.nan   # no bools, no strings
        except (TypeError, ValueError, OverflowError):
            nu_f = np.nan
        if not (np.isfinite(nu_f) and -1 < nu_f < 0.5):
            raise ValueError(f"nu must be a number in (-1, 0.5), got {nu!r}")
        nu = nu_f
        k = (6 * (1 + nu) / (7 + 6 * nu) if shear_coefficient is None
             else positive("shear_coefficient", shear_coefficient))
        E, radius = np.float64(E), np.float64(radius)
        G = E / (2 * (1 + nu))
        with np.errstate(over="ignore", under="ignore"):
            A = np.pi * radius**2
            I = np.pi * radius**4 / 4
            derived = dict(EA=E * A, GA1=k * G * A, GA2=k * G * A, EI1=E * I, EI2=E * I,
                           GJ=G * 2 * I)
        bad = [n for n, v in derived.items() if not (np.isfinite(v) and v > 0)]
        if bad:                                  # blame the inputs, not a derived value
            v = derived[bad[0]]
            raise ValueError(
                f"radius={float(radius)!r} with E={float(E)!r} is out of floating-point "
                f"range: it gives {bad[0]} = {float(v)!r} "
                f"({'overflow' if v > 0 else 'underflow'}); choose units "
                "in which radius and E are closer to 1")
        return cls(radius=radius, **derived)

    @classmethod
    def from_matrix(cls, C, radius=None):
        """Section with a full symmetric positive-definite 6 x 6 stiffness
        ``C`` in the strain order ``(v1, v2, v3, u1, u2, u3)`` (couplings,
        e.g. of stretch and twist, allowed).

        Parameters
        ----------
        C : array_like (6, 6)
        radius : float, optional

        Returns
        -------
        Section

        Examples
        --------
        >>> C = np.diag([10.0, 10.0, 20.0, 1.0, 1.0, 0.8])
        >>> C[2, 5] = C[5, 2] = 0.5                    # stretch-twist coupling
        >>> sec = Section.from_matrix(C)
        >>> sec.EA, sec.GJ, float(sec.C[2, 5])
        (20.0, 0.8, 0.5)
        """
        if isinstance(C, (str, bytes)):
            raise ValueError(f"matrix must be a 6 x 6 array of numbers, got {C!r}")
        try:
            C = np.asarray(C, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise ValueError(f"matrix must be a 6 x 6 array of numbers, got {C!r}") from None
        if C.shape != (6, 6):
            raise ValueError(f"matrix must be 6 x 6, got shape {C.shape}")
        d = np.diag(C)
        return cls(**dict(zip(_NAMES, d)), radius=radius, matrix=C)

    @property
    def C(self):
        """The 6 x 6 stiffness in strain order ``(v1, v2, v3, u1, u2, u3)``.

        Examples
        --------
        >>> Section(EA=3.0, GA1=1.0, GA2=2.0, EI1=4.0, EI2=5.0, GJ=6.0).C.diagonal()
        array([1., 2., 3., 4., 5., 6.])
        """
        if self.matrix is not None:
            return self.matrix
        return np.diag([self.GA1, self.GA2, self.EA, self.EI1, self.EI2, self.GJ])
