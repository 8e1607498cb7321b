"""The lookahead supervisor's rule: the concurrent supervisor, guarded by what is known ahead.

The concurrent supervisor (:mod:`dualpilot.supervisor.concurrent`) checks a plan against
the fires of now (and, with ``+risk``, the forecast's zones) over its next
``check_steps`` steps. The failures the yardstick calls avoidable
(docs/yardstick.md) are then mostly of three kinds: a race to G lost to a fire that
grows over it (the plan, or System 2's target, arrives too late), a UAV boxed in by
fronts that leave the planners no path at their clearance, and a plan that hovers by G
when its target is pushed out of G. The lookahead supervisor adds one rule:

* **Guard the plan with the known future.** The plan about to be flown is checked on the
  known future (:mod:`dualpilot.spacetime.known`: the obstacles of now and the
  forecast's risky cells ahead, never the births to come) over its next
  ``check_steps`` flights, or until it lands in G when that is within ``arrive_steps``;
  a plan that fails, a plan that never lands in G within ``stall_radius_m`` of it, or no
  plan, gives way to a **space-time plan**: the lattice search of the clairvoyant oracle
  (:func:`dualpilot.spacetime.plan.lattice_plan`) run on the known future from the
  UAV's state into G, keeping d_safe (+ ``margin_m``), smoothed in a tube
  (:mod:`dualpilot.spacetime.smooth`). It is flown while it stays clear, for at most
  ``guard_steps`` steps; then the concurrent supervisor chooses again.
* **Escape when boxed in.** When no plan is left to fly (the UAV would brake), the same
  search looks for ``escape_steps`` flights, anywhere, that keep d_safe (+ ``margin_m``)
  from the obstacles of now grown as fast as a front can grow
  (:func:`dualpilot.spacetime.known.growing`: a physics scenario's head fire, a paper
  front's speed; not its redrawn sides): a last resort, closer to the fires than the
  forecast's cells allow; it is flown one step, and the choice is made again at the next.

The search is the supervisor's own and answers like System 1 ("s1:ok[space-time]",
"s1:ok[escape]"):
under the paper's timing it takes System 1's 155 ms; its compute time is recorded as
System 1's. Lengths m.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from dualpilot.spacetime.plan import Stage
from dualpilot.spacetime.plan3 import Stage3


@dataclass(frozen=True)
class LookaheadParams:
    """The guard's settings (lengths m)."""

    #: flights of a plan checked on the known future
    check_steps: int = 10
    #: a plan that lands in G within this many flights is checked until it does
    arrive_steps: int = 25
    #: a plan that never lands in G while the UAV is this close to G's centre has stalled
    stall_radius_m: float = 200.0
    #: a space-time plan is flown at most this many steps before the choice is made again
    guard_steps: int = 10
    #: forecast cells whose occupancy exceeds this count as fire (the planners' α)
    alpha: float = 0.1
    #: kept beyond d_safe from the known future's boxes
    margin_m: float = 0.5
    #: half-side of the tube a space-time plan is smoothed in
    tube_m: float = 3.0
    #: the lattice search's stages (weighted A*, a coarse lattice, a small budget)
    stages: tuple[Stage, ...] = field(default_factory=lambda: (Stage(5.0, 250_000, weight=2.0),))
    #: the 3-D search's stages over low fronts (docs/three_d.md §8): the two altitude levels,
    #: then the band (:mod:`dualpilot.spacetime.plan3`), the planar stage's budget between them
    stages3: tuple[Stage3, ...] = field(default_factory=lambda: (
        Stage3(Stage(5.0, 100_000, weight=2.0), "two"),
        Stage3(Stage(5.0, 150_000, weight=2.0), "band")))
    #: flights an escape must last
    escape_steps: int = 10
    #: the escape search's budget (the same lattice)
    escape_stage: Stage = Stage(5.0, 20_000, weight=2.0)

    def __post_init__(self) -> None:
        if min(self.check_steps, self.arrive_steps, self.guard_steps, self.escape_steps) < 1:
            raise ValueError("check_steps, arrive_steps, guard_steps and escape_steps must be "
                             ">= 1")
        if not (0 <= self.alpha < 1 and self.margin_m >= 0 and self.tube_m >= 0
                and self.stall_radius_m >= 0 and self.stages and self.stages3):
            raise ValueError(f"invalid lookahead parameters: {self}")
