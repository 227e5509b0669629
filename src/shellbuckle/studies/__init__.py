"""Published studies reproduced on top of the general API, one package each.

The library (mesh, energies, solvers, protocol, runs, sweeps, analysis, plots) knows no paper;
a study holds what is particular to one: its scale and special runs, the keys of its
reference numbers and how our runs answer each, and its report. :mod:`.report` is the
machinery a study's report is made with.

- :mod:`shellbuckle.studies.quilliet2008`: Quilliet, Zoldesi, Riera, van Blaaderen and Imhof,
  *Anisotropic colloids through non-trivial buckling*, Eur. Phys. J. E 27, 13 (2008).
"""
