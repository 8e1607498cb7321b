"""What the vehicle saw of its setpoint stream: the gaps between setpoints and the failsafes.

Every setpoint the vehicle accepts from the peer in control is one sample:
the wall time since the previous one (ms, measured when the vehicle read it,
so a vehicle process that was itself kept off the CPU counts against the
stream too). Gaps go into a 0.1 ms histogram up to :data:`MAX_MS` (longer
ones are kept exactly), so memory stays bounded on a long flight and the
quantiles are exact to 0.1 ms. ``--stream-stats PATH`` writes the summary
as JSON every few seconds and at exit (services/uavsim/hosting.py).
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: gaps up to this many ms are binned (0.1 ms bins); longer ones are kept as they are
MAX_MS = 2000.0
BIN_MS = 0.1
QUANTILES = {"p50_ms": 0.5, "p90_ms": 0.9, "p99_ms": 0.99, "p999_ms": 0.999}


@dataclass
class StreamStats:
    """Setpoint gaps (wall ms) and failsafe episodes of one vehicle."""

    bins: np.ndarray = field(default_factory=lambda: np.zeros(int(MAX_MS / BIN_MS) + 1,
                                                              dtype=np.int64))
    long_gaps_ms: list[float] = field(default_factory=list)
    setpoints: int = 0
    failsafes: int = 0
    #: wall s spent in the offboard-loss failsafe, over all episodes
    failsafe_s: float = 0.0
    _last: float = 0.0

    def setpoint(self, now: float, flying: bool) -> None:
        """A setpoint read at ``now`` (monotonic s). Gaps count while ``flying`` (offboard,
        or in the failsafe the stream's loss caused); the first setpoint after the vehicle
        was idle starts a new stream."""
        if self._last and flying:
            self.add_gap((now - self._last) * 1000.0)
        self._last = now
        self.setpoints += 1

    def add_gap(self, gap_ms: float) -> None:
        if gap_ms >= MAX_MS:
            self.long_gaps_ms.append(round(gap_ms, 3))
        else:
            self.bins[int(max(gap_ms, 0.0) / BIN_MS)] += 1

    def failsafe(self) -> None:
        self.failsafes += 1

    @property
    def gaps(self) -> int:
        return int(self.bins.sum()) + len(self.long_gaps_ms)

    def quantile_ms(self, q: float) -> float:
        """The ``q`` quantile of the gaps (upper edge of its 0.1 ms bin; 0.0 with none)."""
        n = self.gaps
        if n == 0:
            return 0.0
        rank = max(1, int(np.ceil(q * n)))
        cum = np.cumsum(self.bins)
        if rank <= cum[-1]:
            return round(float((np.searchsorted(cum, rank) + 1) * BIN_MS), 3)
        return float(sorted(self.long_gaps_ms)[rank - int(cum[-1]) - 1])

    def max_ms(self) -> float:
        if self.long_gaps_ms:
            return max(self.long_gaps_ms)
        nz = np.flatnonzero(self.bins)
        return round(float((nz[-1] + 1) * BIN_MS), 3) if len(nz) else 0.0

    def over(self, limit_ms: float) -> int:
        """How many gaps were longer than ``limit_ms``."""
        first = int(np.ceil(limit_ms / BIN_MS))
        return int(self.bins[first:].sum()) + sum(g > limit_ms for g in self.long_gaps_ms)

    def summary(self, **extra: Any) -> dict[str, Any]:
        gaps: dict[str, Any] = {"n": self.gaps, **{k: self.quantile_ms(q)
                                                   for k, q in QUANTILES.items()},
                                "max_ms": self.max_ms(), "over_150_ms": self.over(150.0),
                                "over_1000_ms": self.over(1000.0)}
        return {"setpoints": self.setpoints, "gaps": gaps, "failsafes": self.failsafes,
                "failsafe_s": round(self.failsafe_s, 3), **extra}

    def write(self, path: str | Path, **extra: Any) -> None:
        """The summary as JSON at ``path``, replaced atomically (raises OSError)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
        try:
            with os.fdopen(fd, "w") as fh:
                json.dump(self.summary(**extra), fh, indent=1)
                fh.write("\n")
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
