"""Layers that point one way: the evaluation computes, the figures draw what it computed.

``dualpilot/viz`` may import ``dualpilot/evaluation`` (a figure of a run's
results); no module of the evaluation imports the figures, at any depth (a lazy
import inside a function counts): ``dualpilot evaluate`` and ``sweep`` draw their
figures in the command line, which hands the plotter in.
"""

from __future__ import annotations

from tests.unit.test_import_cycles import import_graph


def test_the_evaluation_never_imports_the_figures() -> None:
    graph = import_graph()
    evaluation = {m for m in graph if m.startswith("dualpilot.evaluation")}
    assert "dualpilot.evaluation.evaluate" in evaluation
    wrong = sorted(f"{m} -> {t}" for m in evaluation for t in graph[m]
                   if t.startswith("dualpilot.viz"))
    assert wrong == []
    assert any(t.startswith("dualpilot.evaluation") for m in graph if m.startswith(
        "dualpilot.viz") for t in graph[m]), "the figures read the evaluation's results"
