"""One mission's verdict: feasible (a flown witness), impossible (a certificate) or unknown.

:func:`solve` searches for a witness (:mod:`~dualpilot.oracle.search`) and flies it
through the mission step (:mod:`~dualpilot.oracle.witness`); without one it runs the
certificate (:mod:`~dualpilot.oracle.certificate`). Both read the same fire future
(:mod:`~dualpilot.oracle.future`). A 3-D mission whose every front is taller than any UAV
flies is judged by the planar oracle of its 2-D twin, the witness lifted and flown in 3-D
(:mod:`~dualpilot.oracle.reduction`); any other by the certificate's columns
(:mod:`~dualpilot.oracle.columns`) and the lattice over the band
(:mod:`~dualpilot.oracle.search3`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.ports import FirePort
from dualpilot.mission.result import MissionResult
from dualpilot.oracle.certificate import Certificate, CertificateParams, ReachableSet
from dualpilot.oracle.columns import ReachableColumns
from dualpilot.oracle.future import FireFuture, Future
from dualpilot.oracle.reduction import lift, not_reduced, planar_twin
from dualpilot.oracle.search import SearchOutcome, SearchParams, search
from dualpilot.oracle.search3 import SearchParams3, search3
from dualpilot.oracle.witness import fly_witness

log = logging.getLogger(__name__)

FEASIBLE, IMPOSSIBLE, UNKNOWN = "feasible", "impossible", "unknown"


@dataclass(frozen=True)
class OracleParams:
    """The witness search's lattice and budget, and the certificate's grid and scope."""

    search: SearchParams = field(default_factory=SearchParams)
    #: the search over the band, of a 3-D mission that does not reduce to the plane
    search3: SearchParams3 = field(default_factory=SearchParams3)
    certificate: CertificateParams = field(default_factory=CertificateParams)


@dataclass(frozen=True)
class Verdict:
    """The oracle's answer for one mission, with the witness's flight when it is feasible.

    ``problem`` is non-empty only when a witness was found but did not fly to G (a defect
    of the search: its future or its rules differ from the mission's).
    """

    verdict: str
    reason: str
    flight: MissionResult | None = None
    expansions: int = 0
    certificate: Certificate | None = None
    problem: str = ""
    seconds: float = 0.0


#: the dimensions (``DynamicsParams.dim``) of the missions the oracle judges
DIMS = frozenset({2, 3})


def check_dimension(config: MissionConfig) -> None:
    """Nothing if the oracle judges ``config``'s mission; else ValueError naming why not."""
    dim = config.spec().dim
    if dim not in DIMS:
        raise ValueError(f"the oracle judges missions of dim 2 and 3, not dim={dim}")


#: what judges a mission: its fire future, its certificate and its search
Judge = tuple[Future, ReachableSet | ReachableColumns, Callable[[], SearchOutcome]]


def judge(config: MissionConfig, params: OracleParams, future: Future | None) -> Judge:
    """The fire future, the certificate and the search of ``config``'s mission: the planar
    ones (of its planar twin, the witness lifted, when a 3-D mission reduces to the plane:
    :mod:`~dualpilot.oracle.reduction`), else those over the band (:mod:`.columns`,
    :mod:`.search3`: ``future`` then has rows with the tops)."""
    if config.spec().dim == 3 and not_reduced(config):
        band_future = FireFuture(config) if future is None else future
        return (band_future, ReachableColumns(config, band_future, params.certificate),
                lambda: search3(config, band_future, params.search3))
    planar = planar_twin(config)
    flat_future = FireFuture(planar) if future is None else future

    def lifted() -> SearchOutcome:
        found = search(planar, flat_future, params.search)
        if found.witness is None:
            return found
        return replace(found, witness=lift(found.witness, config))

    return flat_future, ReachableSet(planar, flat_future, params.certificate), lifted


def solve(config: MissionConfig, params: OracleParams = OracleParams(),
          future: Future | None = None, fires: FirePort | None = None) -> Verdict:
    """The verdict on ``config``'s mission (its seed, start, goal and reading); ``future`` and
    ``fires`` replace its fire future and its fire port (a scripted fire, in the tests).

    The certificate runs first over the sub-steps the oracle's own flights can see (one a
    step): a set that empties there, or never meets G there, needs no search; one that meets
    G, or a certificate that gives up, leaves the answer to the search.
    """
    t0 = time.perf_counter()
    check_dimension(config)
    future, reach, find = judge(config, params, future)
    cert = reach.run(config.reading().mission.max_steps * future.substeps_per_step)
    if cert is not None and cert.verdict == IMPOSSIBLE:
        return Verdict(IMPOSSIBLE, cert.reason, None, 0, cert, seconds=time.perf_counter() - t0)
    expansions, why, problem = 0, "not run: G out of reach of one sub-step steps", ""
    if cert is not None:  # G within reach, or the certificate cannot tell: search
        found = find()
        expansions, why = found.expansions, found.reason
        if found.witness is not None:
            flight, replay = fly_witness(config, found.witness, fires)
            if flight.success:
                return Verdict(FEASIBLE, "witness flown to G", flight, expansions, cert,
                               seconds=time.perf_counter() - t0)
            problem = (f"the witness did not reach G: {flight.failure_cause} at step "
                       f"{flight.steps}; monitor {replay.refusals[:1]}")
            log.error("seed %d: %s", config.seed, problem)
    if cert is None:
        cert = reach.run()
        assert cert is not None
    if cert.verdict == IMPOSSIBLE and not problem:
        return Verdict(IMPOSSIBLE, cert.reason, None, expansions, cert,
                       seconds=time.perf_counter() - t0)
    return Verdict(UNKNOWN, f"search {why}; certificate {cert.verdict}: {cert.reason}", None,
                   expansions, cert, problem, time.perf_counter() - t0)
