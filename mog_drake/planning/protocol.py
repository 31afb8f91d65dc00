"""What the planner needs from a physics check: the `Verifier` protocol and its result."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np


@dataclass
class GraspResult:
    """Outcome of CheckGraspSuccess() for one grasp u on one group.

    success: every group object was held between the jaws and lifted (extra non-group
    objects lifted count as a bonus, never as a failure). lifted: ids of every object lifted.
    error: empty when the check ran as intended; otherwise what went wrong, and then
    success is always False.
    """

    success: bool
    lifted: list[int] = field(default_factory=list)
    final_opening: float = float("nan")  # inner distance between the jaws at the end (m)
    sim_time: float = 0.0  # simulated seconds
    wall_time: float = 0.0  # seconds of computation (includes a plant build if one was needed)
    built: bool = False  # whether this check had to build a plant
    bodies: int = 0  # object bodies simulated (0: none, or not told)
    error: str = ""
    # False when the check stopped early because its verdict was already certain: ``lifted``
    # is then only what was in the air at that moment, not objects held to the end.
    complete: bool = True
    # A robust check's refusal (its screen or its perturbed worlds), not its nominal check's:
    # the nominal check alone may still take the grasp (`planning.robust`).
    not_robust: bool = False

    def text(self) -> str:
        opening = "-" if np.isnan(self.final_opening) else f"{self.final_opening * 1e3:.2f} mm"
        return (
            f"physics    success {self.success}   lifted {self.lifted}   opening {opening}   "
            f"{self.sim_time:.2f} s simulated in {self.wall_time:.2f} s"
            + (f"   error: {self.error}" if self.error else "")
        )

    def to_dict(self) -> dict:
        d = asdict(self)
        d["final_opening"] = None if np.isnan(self.final_opening) else float(self.final_opening)
        return d


@runtime_checkable
class Verifier(Protocol):
    """Anything that can tell whether a grasp lifts its group (the paper's CheckGraspSuccess)."""

    def check(self, scene, group, grasp) -> GraspResult: ...
