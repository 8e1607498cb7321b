""""thorough": the fast method with every homotopy iterated to convergence.

Slower than "fast"; one more reference in the benchmark (``dualpilot bench system2``).
"""

from __future__ import annotations

from dualpilot.spec import MissionSpec
from dualpilot.system2.fast.params import FastParams
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.problem import System2Params

THOROUGH = FastParams(max_homotopies=16, max_signature_hulls=8, length_slack=1.5,
                      max_iterations=40, rel_tol=1e-9, screen_slack=100.0,
                      max_prefeasible=8, max_qp=1000)
"""FastParams of the "thorough" method: no screening, no time budget."""


class ThoroughSystem2(FastSystem2):
    """"thorough": the fast method with :data:`THOROUGH`'s knobs."""

    method = "thorough"

    def __init__(self, spec: MissionSpec, params: System2Params = System2Params()) -> None:
        super().__init__(spec, params, THOROUGH)
