"""The settings of one vehicle link (the companion's side of MAVLink)."""

from __future__ import annotations

from dataclasses import dataclass

#: who sends the stream: the stream process (UDP links), or a thread of this process (a link
#: that is not UDP, and the comparison of benchmarks/stream_gaps.py)
STREAMS = ("process", "thread")


@dataclass(frozen=True)
class LinkParams:
    """How the supervisor talks MAVLink to one vehicle (system ``target_system``, component 1)."""

    url: str
    target_system: int = 1
    altitude_m: float = 50.0  # the setpoints' altitude above home (m)
    #: the setpoint stream's rate (Hz; ≥ 10, PX4 needs ≥ 2)
    rate_hz: float = 20.0
    passphrase: str = ""  # MAVLink 2 signing (or ``key``: 32 bytes)
    key: bytes | None = None
    #: the vehicle counts as lost after this long without a heartbeat (s)
    lost_after_s: float = 3.0
    #: a refused or unanswered COMMAND_LONG is sent this many times, each waiting this long (s)
    command_attempts: int = 3
    command_timeout_s: float = 1.0
    stream: str = "process"  # :data:`STREAMS`

    def __post_init__(self) -> None:
        if self.rate_hz < 10:
            raise ValueError(f"setpoints are streamed at >= 10 Hz, got {self.rate_hz}")
        if self.stream not in STREAMS:
            raise ValueError(f"stream must be one of {STREAMS}, got {self.stream!r}")

    @property
    def period_s(self) -> float:
        """The setpoint stream's period (s)."""
        return 1.0 / self.rate_hz
