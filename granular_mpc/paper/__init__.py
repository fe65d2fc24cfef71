"""The paper comparison (issue 10 item 6): does the package reproduce Chen et al.?

:func:`paper_comparison` runs the paper's protocols and writes ``paper_comparison.md``: one
row per claim of the paper, with the paper's value, ours, their ratio, the protocol and,
where they differ, the measured reason. Modules, one job each: ``runs`` (what is run),
``measures`` (figures of a run folder), ``model_check`` (the two models against a data
set), ``claims`` (the rows), ``gaps`` (the measured reasons of the rows that differ,
from ``bench/paper_gaps.py``), ``figures``, ``table`` (the Markdown), ``comparison`` (the one
call). Protocols and how to read the table: ``docs/paper.md``.
"""

from .claims import ClaimRow
from .comparison import PaperComparison, paper_comparison, tabulate
from .gaps import GapAblations, load_gaps
from .runs import PaperRuns, RunPlan

__all__ = ["paper_comparison", "tabulate", "PaperComparison", "ClaimRow", "PaperRuns", "RunPlan",
           "GapAblations", "load_gaps"]
