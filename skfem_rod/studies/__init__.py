"""Studies: sweeps of shipped scenes with their analysis and figure
(run one with ``python -m skfem_rod.studies.NAME``; docs/sweep.md)."""
