"""Warm a fire process's forecast before a mission asks for it: the first costs ~0.2-0.6 s.

The first occupancy forecast a process makes loads its compiled kernels (and,
for a fire-behaviour scenario, builds the fuel model's tables), ~0.4 s for the
paper's process and 0.2-0.8 s for a scenario, against ~10 ms once warm: longer
than the supervisor waits for a forecast (half a step), so a mission's first
step would plan without one (a ``forecast_stale`` fault).

The EWS warms only the fire process a mission runs, once a process: the first
reset that runs it starts one forecast of that process in the background
(:class:`Warmer`), the reset's reply goes out at once, and the first forecast
of the mission waits for the warm-up. Between the reset and the mission's first
forecast the supervisor prepares its planners and advances the fires of step 0,
so the warm-up is done by then; the EWS announces itself without making any.
"""

from __future__ import annotations

import logging
import threading
import time

from dualpilot.model.field_forecast import field_forecast
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.model.forecast import ForecastParams
from dualpilot.spec import Stream, stream_rng
from services.common.log import fields

log = logging.getLogger("services.ews")

#: sub-steps a warm-up fire process runs at most before its forecast (until a front lives)
MAX_SUBSTEPS = 200


def warm_process(params: FireParams, forecast: ForecastParams) -> float:
    """One forecast of ``params``' fire process (the paper's or its scenario) from its first
    front, on ``forecast``'s grid; the wall time it took (s)."""
    t0 = time.perf_counter()
    field = FireField(params=params)
    rng = stream_rng(0, Stream.FIRE)
    for _ in range(MAX_SUBSTEPS):
        if field.fronts:
            break
        field.substep(rng, field.substeps_done)
    field_forecast(field, forecast, 0, 1)
    return time.perf_counter() - t0


class Warmer:
    """Each fire process (by its scenario name) warmed once in this process, in a thread of
    its own, from the first :meth:`start` that names it; :meth:`wait` until it is warm."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._runs: dict[str, threading.Thread] = {}
        #: the wall time each warm-up took (s), by scenario, once done
        self.took: dict[str, float] = {}

    def start(self, params: FireParams, forecast: ForecastParams) -> bool:
        """Start warming ``params``' fire process unless it was started before; True if this
        call started it."""
        name = params.scenario
        with self._lock:
            if name in self._runs:
                return False
            run = threading.Thread(target=self._warm, args=(params, forecast), daemon=True,
                                   name=f"warm-{name}")
            self._runs[name] = run
        run.start()
        return True

    def _warm(self, params: FireParams, forecast: ForecastParams) -> None:
        try:
            took = warm_process(params, forecast)
        except Exception:  # the mission's own forecast will say what is wrong
            log.exception("forecast warm-up failed", extra=fields(scenario=params.scenario))
            return
        self.took[params.scenario] = took
        log.info("forecast warmed", extra=fields(scenario=params.scenario, s=round(took, 3)))

    def wait(self, params: FireParams, timeout_s: float | None = None) -> None:
        """Return once ``params``' fire process is warm, or was never started (or after
        ``timeout_s``)."""
        with self._lock:
            run = self._runs.get(params.scenario)
        if run is not None:
            run.join(timeout_s)

    def started(self) -> list[str]:
        """The fire processes warmed or being warmed, in the order they were started."""
        with self._lock:
            return list(self._runs)
