"""The demo scripts, shipped with the package (``skfem-rod demo NAME``).

Each is a literate script with ``main(out, ...)`` and ``SMALL`` settings; in
a source checkout they are also reachable as ``demos/NAME.py``."""
