"""The physics check's settings (the scenario's ``verifier:`` section): its contact model,
the table it stands on, the close, lift and hold, and when a hold ends."""

from dataclasses import dataclass, field

from mog_drake.config import in_range
from mog_drake.errors import MogError
from mog_drake.geometry import GripperGeometry
from mog_drake.sim.models import ContactConfig, GripperPhysics


def check_contact() -> ContactConfig:
    """The check's contact: the world's friction, with polygon contact surfaces (triangles cost
    1.7x for the same verdicts) on a half-space table (0.88x the box's CPU, as many verdicts
    equal to the reference's)."""
    c = ContactConfig(table_collision="halfspace")
    c.plant.contact_surface_representation = "polygon"
    return c


@dataclass
class VerifierConfig:
    """The physics check's own settings (the jaws' geometry and dynamics are the station's:
    `DrakeVerifier`): the picking planner's check (docs/physics.md has the evidence for each
    value). The paper's row experiments use their own (models/row_check.yaml).

    Its model is the world's own contact (table friction changes how pushed objects turn and
    slide; with the paper's near-frictionless table the check promised groups the world did
    not lift). It lifts 0.15 m and holds up to 2.5 s, as long as the arm takes to lift and
    carry a grasp to the bin (a thin bar on its side, held end to end, slips out about 2 s
    after the lift), but ends the hold as soon as no lifted object has moved 0.06 mm in
    0.1 s: a grip that holds moves with the jaws. It simulates only the objects this grasp's
    jaws and the group can touch (``bodies: grasp``), and a check that holds two or more of
    the group runs to the end to say which (for planner.loop.partial_lifts; one lifted object
    is not worth the hold: a lone object's own check is as cheap)."""

    contact: ContactConfig = field(default_factory=check_contact)
    settle_time: float = 0.05  # s, objects settle on the table before the jaws move
    squeeze_time: float = 0.15  # s, jaws keep pushing after the closing ramp
    lift_height: float = 0.15  # m
    lift_speed: float = 0.30  # m/s (mean)
    hold_time: float = 2.5  # s, held in the air at most before the verdict
    lifted_fraction: float = 0.5  # an object is lifted if it rose by this fraction of the lift
    # CPU seconds the checking thread may spend on one check before it is abandoned. CPU time,
    # not wall time: a thread starved by a busy machine must not turn waiting into a verdict;
    # the thread's, not the process's: planning runs beside the station's physics.
    cpu_budget: float = 30.0
    reach_margin: float = 0.02  # m, extra radius when choosing which objects to simulate
    # Which objects a check simulates besides the group: "group", every object the jaws of
    # any grasp of the group can reach (`objects_in_reach`; one plant serves the group's
    # candidates); or "grasp" (an extension), only those within grasp_margin of this grasp's
    # swept jaws or of a group object's bounding disc (`objects_at_grasp`): a plant per set,
    # about 30 ms to build, against 2-3 ms per 2 ms step with a whole neighbourhood of
    # resting objects in contact with the table (1 ms with the group alone).
    bodies: str = "grasp"
    grasp_margin: float = 0.005  # m
    # Stop a check as soon as its failure is certain: during the lift, once the fingers'
    # bottom is above the top of a group object still resting near the table, that object
    # can never be lifted (the gripper only rises from then on). Same verdict, less time.
    early_exit: bool = True
    # With early_exit: stop when any group object is certainly left (the verdict is then
    # known); or, with report_partial_lifts = k > 0, only once fewer than k group objects may
    # still be lifted, so that a check lifting k or more of the group runs to the end and
    # reports which objects it held (k = 1: wait until every group object is left).
    report_partial_lifts: int = 2
    # An extension (0: off, the whole hold is simulated): end the hold early once every
    # lifted object has moved slower than settle_speed for settle_window seconds. A grip
    # that will slip creeps from the start of the hold, and faster and faster; a grip that
    # holds creeps at a steady few tenths of a mm/s (the compliant contact's regularised
    # friction). An object's speed here is that of its origin plus its angular speed times
    # its farthest point's distance from it (to first order, the fastest any point of it
    # moves); the test is on the fastest lifted object's speed averaged over the window. A
    # bar on its side held end to end: 1.9 mm/s 0.1 s into the hold, 3.1 mm/s at 0.6 s, and
    # it drops at 1.1 s; held across: 0.4-0.6 mm/s, with one-sample spikes up to 1.2 mm/s.
    settle_window: float = 0.0  # s
    settle_speed: float = 0.001  # m/s
    # Ends the hold once no lifted object's origin has moved more than hold_drift over the
    # last hold_window (0: off). A grip that will fail lets its object creep, and faster and
    # faster; a held one moves with the jaws (still, in the hold) but for the compliant
    # contact's few tenths of a mm/s, however its velocity chatters from step to step.
    hold_window: float = 0.1  # s
    hold_drift: float = 0.00006  # m

    def check(self, where: str = "verifier") -> None:
        """Refuses, at load, a setting the check cannot run with (the key named)."""
        if not 0 < self.hold_time <= 30:
            raise MogError(f"{where}.hold_time must be in (0, 30] s, got {self.hold_time}")
        for key in ("settle_window", "hold_window"):
            if not 0 <= getattr(self, key) <= self.hold_time:
                raise MogError(
                    f"{where}.{key} must be in [0, hold_time = {self.hold_time:g}] s, got {getattr(self, key)}"
                )
        if self.bodies not in ("group", "grasp"):
            raise MogError(f"{where}.bodies must be one of group, grasp, got {self.bodies!r}")
        for key, hi in (("cpu_budget", 600), ("hold_drift", 0.05), ("lift_height", 0.5), ("lift_speed", 2.0)):
            in_range(getattr(self, key), f"{where}.{key}", 0, hi)
        for key in ("settle_time", "squeeze_time", "grasp_margin", "reach_margin"):
            in_range(getattr(self, key), f"{where}.{key}", 0, 10, lo_open=False)
        if not 0 < self.lifted_fraction < 1:
            raise MogError(f"{where}.lifted_fraction must be in (0, 1), got {self.lifted_fraction}")
        self.contact.check(f"{where}.contact")

    @property
    def lifted_height(self) -> float:
        """Height (m) above which an object counts as lifted."""
        return self.lifted_fraction * self.lift_height

    def timeline(self, gripper: GripperGeometry, physics: GripperPhysics) -> dict[str, float]:
        """When each phase of the check starts and ends (s)."""
        t_close0 = self.settle_time
        t_close1 = t_close0 + (gripper.opening - gripper.plate_thickness) / 2 / physics.close_speed
        t_lift0 = t_close1 + self.squeeze_time
        t_lift1 = t_lift0 + self.lift_height / self.lift_speed
        return {
            "close0": t_close0,
            "close1": t_close1,
            "lift0": t_lift0,
            "lift1": t_lift1,
            "end": t_lift1 + self.hold_time,
        }
