"""Quilliet et al., Eur. Phys. J. E 27, 13 (2008), reproduced.

- :mod:`.reproduce`: the paper's whole numerical study in one call (:class:`Study`,
  :func:`reproduce_paper`: a resumable sweep, the special runs of Figs. 3 and 11 and the
  re-inflation, the figures and the report); ``shellbuckle reproduce-paper``.
- :mod:`.conventions`: the study under each reading of the paper's bending energy, scored
  against every number of the paper (:func:`compare_conventions`);
  ``shellbuckle reproduce-paper --compare-conventions``.
- :mod:`.report`: the reproduction report, our numbers next to each entry of the paper's
  reference file (:func:`write_report`); ``shellbuckle report``.

The paper's numbers ship with the package (``shellbuckle/data/quilliet2008.json``,
:func:`shellbuckle.analysis.collect.load_reference`). ``shellbuckle.reproduce``,
``shellbuckle.convention_study`` and ``shellbuckle.report`` are the former names of these
modules and stay importable.
"""

from .conventions import compare_conventions
from .report import write_report
from .reproduce import PAPER_GAMMAS, Study, reproduce_paper

__all__ = ["PAPER_GAMMAS", "Study", "compare_conventions", "reproduce_paper", "write_report"]
