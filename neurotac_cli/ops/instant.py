"""What every sync method finds: the instant t0 on the camera clock, with its score and details."""

from dataclasses import dataclass, field


@dataclass
class Instant:
    t0: int
    score: float | None = None
    details: dict = field(default_factory=dict)
