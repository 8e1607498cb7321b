"""One mission's verdict: feasible (a flown witness), impossible (a certificate) or unknown.

:func:`solve` searches for a witness (:mod:`~dualpilot.oracle.search`) and flies it
through the mission step (:mod:`~dualpilot.oracle.witness`); without one it runs the
certificate (:mod:`~dualpilot.oracle.certificate`). Both read the same fire future
(:mod:`~dualpilot.oracle.future`). A 3-D mission is judged when every front is taller than
the band, by the planar oracle of its 2-D twin, the witness lifted and flown in 3-D
(:mod:`~dualpilot.oracle.reduction`); any other is refused.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.ports import FirePort
from dualpilot.mission.result import MissionResult
from dualpilot.oracle.certificate import Certificate, CertificateParams, ReachableSet
from dualpilot.oracle.future import FireFuture, Future
from dualpilot.oracle.reduction import lift, planar_twin, refusal
from dualpilot.oracle.search import SearchParams, search
from dualpilot.oracle.witness import fly_witness

log = logging.getLogger(__name__)

FEASIBLE, IMPOSSIBLE, UNKNOWN = "feasible", "impossible", "unknown"


@dataclass(frozen=True)
class OracleParams:
    """The witness search's lattice and budget, and the certificate's grid and scope."""

    search: SearchParams = field(default_factory=SearchParams)
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


#: the dimensions (``DynamicsParams.dim``) of the missions the oracle judges: a 3-D one only
#: when every front is taller than any UAV can fly (:func:`~dualpilot.oracle.reduction.refusal`)
DIMS = frozenset({2, 3})


def check_dimension(config: MissionConfig) -> None:
    """Nothing if the oracle judges ``config``'s mission; else ValueError naming why not
    (:func:`~dualpilot.oracle.reduction.refusal`)."""
    dim = config.spec().dim
    if dim not in DIMS:
        raise ValueError(f"the oracle judges missions of dim {sorted(DIMS)}, not dim={dim}")
    why = refusal(config)
    if why:
        raise ValueError(why)


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
    planar = planar_twin(config)  # a 3-D mission with every front taller than the band
    future = FireFuture(planar) if future is None else future
    reach = ReachableSet(planar, future, params.certificate)
    cert = reach.run(planar.reading().mission.max_steps * future.substeps_per_step)
    if cert is not None and cert.verdict == IMPOSSIBLE:
        return Verdict(IMPOSSIBLE, cert.reason, None, 0, cert, seconds=time.perf_counter() - t0)
    expansions, why, problem = 0, "not run: G out of reach of one sub-step steps", ""
    if cert is not None:  # G within reach, or the certificate cannot tell: search
        found = search(planar, future, params.search)
        expansions, why = found.expansions, found.reason
        if found.witness is not None:
            flight, replay = fly_witness(config, lift(found.witness, config), fires)
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
