"""What a link does to the frames of one direction: delay, jitter, loss and a bandwidth.

Delay, jitter and loss are applied per frame (netem's ``delay D J loss P``; the user-space
impairer, :mod:`services.testbed.impairer`, where the kernel has no netem); the bandwidth is a
``tc tbf`` token bucket on the link's egress (:mod:`services.testbed.shaping`). The defaults
are a perfect link.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

#: bounds that catch a unit slip (seconds for milliseconds, percent for a fraction)
MAX_DELAY_MS = 60_000.0
MAX_RATE_MBIT = 10_000.0


def _number(name: str, value: Any, low: float, high: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and low <= v <= high):
        raise ValueError(f"{name} must be in [{low:g}, {high:g}], got {value!r}")
    return v


@dataclass(frozen=True)
class Impairment:
    """One direction of a link.

    Parameters
    ----------
    delay_ms : one-way delay added to every frame, ms.
    jitter_ms : each frame's delay is drawn uniformly from ``delay_ms ± jitter_ms`` (netem's
        distribution without a table), clipped at 0; frames stay in order.
    loss : probability that a frame is dropped, independently of the others, in [0, 1].
    rate_mbit : the link's bandwidth, Mbit/s (``tc tbf``); None: not limited.
    queue_ms : how long a full token bucket's queue takes to drain at ``rate_mbit``, ms (the
        radio modem's buffer); a frame that finds it full is dropped.
    """

    delay_ms: float = 0.0
    jitter_ms: float = 0.0
    loss: float = 0.0
    rate_mbit: float | None = None
    queue_ms: float = 500.0

    def __post_init__(self) -> None:
        _number("delay_ms", self.delay_ms, 0.0, MAX_DELAY_MS)
        _number("jitter_ms", self.jitter_ms, 0.0, MAX_DELAY_MS)
        _number("loss", self.loss, 0.0, 1.0)
        if self.rate_mbit is not None:
            _number("rate_mbit", self.rate_mbit, 1e-3, MAX_RATE_MBIT)
        _number("queue_ms", self.queue_ms, 1.0, MAX_DELAY_MS)

    @property
    def per_frame(self) -> bool:
        """True when frames are delayed or dropped (more than a bandwidth)."""
        return self.delay_ms > 0 or self.jitter_ms > 0 or self.loss > 0

    def wire(self) -> dict[str, Any]:
        """The fields as a JSON-ready dict (the impairer's control messages)."""
        return asdict(self)

    @classmethod
    def from_wire(cls, doc: Any) -> Impairment:
        """Checked inverse of :meth:`wire` (ValueError on an unknown field or a bad value)."""
        if not isinstance(doc, dict):
            raise ValueError(f"an impairment is a JSON object, got {doc!r}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(doc) - known)
        if unknown:
            raise ValueError(f"unknown impairment fields {unknown} (known: {sorted(known)})")
        return cls(**doc)
