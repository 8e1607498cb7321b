"""One direction of an impaired link, on injected times: loss, delay with jitter, outages.

A frame offered at time ``now`` is dropped with probability ``loss`` (a Bernoulli draw of
the channel's own seeded stream), else it is due ``delay ± jitter`` later (uniform, clipped at
0, as netem without a distribution table) and never before the frame ahead of it: the
channel delivers in order, as a radio link with link-layer retransmission does. While the link
is down (:class:`Outage`) no frame enters and none leaves: a frame offered during an outage,
or due during one, is blackholed. Times are seconds on one monotonic clock; nothing here reads
a clock, so the tests feed the times.
"""

from __future__ import annotations

import math
import random
from collections import deque
from dataclasses import asdict, dataclass


class Outage:
    """When the link is down: from a start for a duration, or until told otherwise."""

    def __init__(self) -> None:
        self._windows: list[tuple[float, float]] = []

    def begin(self, now: float, seconds: float) -> float:
        """The link is down over [now, now + seconds); returns the end (``inf`` for ever)."""
        if not seconds > 0:
            raise ValueError(f"an outage lasts > 0 s, got {seconds!r}")
        end = now + seconds
        self._windows = [w for w in self._windows if w[1] > now] + [(now, end)]
        return end

    def end(self, now: float) -> None:
        """The link is up again from ``now`` (every open window closes)."""
        self._windows = [(a, min(b, now)) for a, b in self._windows if a < now]

    def down_at(self, t: float) -> bool:
        return any(a <= t < b for a, b in self._windows)

    def until(self, now: float) -> float | None:
        """The end of the outage holding at ``now`` (None: the link is up)."""
        ends = [b for a, b in self._windows if a <= now < b]
        return max(ends) if ends else None


@dataclass
class Counters:
    """What a direction did, in frames and bytes (what the tests and the benchmark read)."""

    offered: int = 0
    offered_bytes: int = 0
    delivered: int = 0
    delivered_bytes: int = 0
    lost: int = 0          # the random loss
    blackholed: int = 0    # offered or due during an outage
    queue_full: int = 0    # refused by the bandwidth's queue (tbf) when sent

    def wire(self) -> dict[str, int]:
        return asdict(self)


class Channel:
    """One direction: a seeded loss/delay model in front of a FIFO delay line."""

    def __init__(self, seed: int | str, outage: Outage, delay_ms: float = 0.0,
                 jitter_ms: float = 0.0, loss: float = 0.0):
        self._rng = random.Random(seed)
        self.outage = outage
        self.counters = Counters()
        self._line: deque[tuple[float, bytes]] = deque()
        self._last_due = -math.inf
        self.delay_ms = self.jitter_ms = self.loss = 0.0
        self.configure(delay_ms, jitter_ms, loss)

    def configure(self, delay_ms: float, jitter_ms: float, loss: float) -> None:
        """New delay, jitter (ms) and loss (0..1) for the frames offered from now on."""
        if not (delay_ms >= 0 and jitter_ms >= 0 and 0 <= loss <= 1):
            raise ValueError(f"delay {delay_ms} ms, jitter {jitter_ms} ms, loss {loss}: "
                             "delay and jitter >= 0, loss in [0, 1]")
        self.delay_ms, self.jitter_ms, self.loss = float(delay_ms), float(jitter_ms), float(loss)

    def offer(self, now: float, frame: bytes) -> float | None:
        """Take a frame arriving at ``now``; returns when it is due, or None if dropped."""
        c = self.counters
        c.offered += 1
        c.offered_bytes += len(frame)
        if self.outage.down_at(now):
            c.blackholed += 1
            return None
        if self.loss > 0 and self._rng.random() < self.loss:
            c.lost += 1
            return None
        delay = self.delay_ms
        if self.jitter_ms > 0:
            delay += self._rng.uniform(-self.jitter_ms, self.jitter_ms)
        due = max(now + max(delay, 0.0) / 1000.0, self._last_due)
        self._last_due = due
        self._line.append((due, frame))
        return due

    def next_due(self) -> float | None:
        return self._line[0][0] if self._line else None

    def due(self, now: float) -> list[bytes]:
        """Frames whose time has come by ``now``, in order (those due in an outage dropped)."""
        out = []
        line = self._line
        while line and line[0][0] <= now:
            t, frame = line.popleft()
            if self.outage.down_at(t):
                self.counters.blackholed += 1
            else:
                out.append(frame)
        return out

    def sent(self, frame: bytes, accepted: bool) -> None:
        """Count a due frame handed to the interface (``accepted``: not refused by its queue)."""
        if accepted:
            self.counters.delivered += 1
            self.counters.delivered_bytes += len(frame)
        else:
            self.counters.queue_full += 1

    def queued(self) -> int:
        return len(self._line)
