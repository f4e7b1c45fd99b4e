"""skfem_rod: geometrically exact Cosserat rods on scikit-fem.

Equilibria of elastic rods (stretch, shear, bending, twist) under large
displacements, with self-contact and Coulomb self-friction (Latrach &
Chamekh).  The internal work is written as scikit-fem forms on a 1D mesh of
nodal cubic (P3) elements; see :mod:`skfem_rod.forms`.

>>> import numpy as np
>>> from skfem_rod import Rod, Section, geometry
>>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 8)
>>> rod.clamp("start").add_force("end", [0.0, 0.5, 0.0])   # doctest: +ELLIPSIS
<skfem_rod.model.Rod object at ...>
"""
from . import geometry
from .model import Rod
from .results import Result
from .section import Section

__all__ = ["Rod", "Section", "Result", "geometry", "sweep"]


def __getattr__(name):
    # skfem_rod.sweep (skfem_rod.sweeps.sweep) on first use: its module is
    # light, Dask and xarray are imported only when a sweep runs
    if name == "sweep":
        from .sweeps import sweep
        return sweep
    raise AttributeError(f"module 'skfem_rod' has no attribute {name!r}")
__version__ = "0.1.0"
