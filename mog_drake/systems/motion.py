"""UR5 motions for one pick: inverse kinematics to gripper poses, time-parameterised by TOPP-RA
within the arm's joint velocity and acceleration limits.

The gripper pose is its palm frame: z up, x along the closing axis, fingertips
`finger_height` below. Descents and lifts are straight vertical lines (IK at several heights,
joined by a cubic through them), so the open jaws come down beside the objects, never across.
"""

import contextlib
import logging

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.optimization import CalcGridPointsOptions, Toppra
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import FixedOffsetFrame
from pydrake.solvers import Solve
from pydrake.trajectories import PathParameterizedTrajectory, PiecewisePolynomial

from mog_drake.config import MotionConfig
from mog_drake.errors import MogError
from mog_drake.geometry.push import ease, push_duration
from mog_drake.sim.models import drake_log_level
from mog_drake.sim.ur5 import URDF_PATH, ArmFrames, base_transform, palm_in_flange

# The arm's links (elbow to flange) stay this high over the table top on every planned move
# (m; at least 0.15 m in every pick on the table): a plan that would take one lower is refused.
LINK_FLOOR = 0.10
LINKS = ("elbow", "wrist 1", "wrist 2", "wrist 3", "flange")


def wrist_in_band(q, center: float = 0.0) -> np.ndarray:
    """``q`` with its last joint (the wrist's turn, which reaches the same pose every full
    turn) in (center - pi, center + pi]: targets chosen this way keep the wrist from winding up
    from one grasp to the next when the arm goes from the bin straight on, and from reaching
    its limit."""
    q = np.array(q, float)
    q[5] = q[5] - 2 * np.pi * np.ceil((q[5] - center - np.pi) / (2 * np.pi))
    return q


def passing_time(traj, q, step: float = 0.005) -> float:
    """The time (s) at which ``traj`` passes nearest to joint configuration ``q`` (sampled
    every ``step`` s)."""
    t = np.arange(0.0, traj.end_time() + step, step)
    t = np.minimum(t, traj.end_time())
    d = [np.abs(traj.value(ti).ravel() - q).max() for ti in t]
    return float(t[int(np.argmin(d))])


class ArmMotion:
    """IK and time parameterisation on an arm-only copy of the station's UR5."""

    def __init__(
        self,
        base_xyyaw,
        max_speed: float,
        max_accel: float,
        config: MotionConfig | None = None,
        finger_height: float = 0.040,
        finger_clearance: float = 0.002,
        *,
        q_home=None,
    ):
        """``finger_height``: the fingertips below the palm (m); ``finger_clearance``: the
        fingertips above the table at the grasp (m), both the gripper's (GripperPhysics);
        ``q_home``: the observe pose. Where given, every target's IK starts from it, so that
        each lies on its branch whatever the arm did before (chained from drop to grasp to
        push, a pose reached from a push by the robot's base could leave the next approach
        on another branch, its elbow 9 cm over the table), and the wrist's band
        (`wrist_in_band`) is centred on its wrist."""
        self.q_home = None if q_home is None else np.asarray(q_home, float)
        self.wrist_center = 0.0 if q_home is None else float(self.q_home[5])
        self.config = config or MotionConfig()
        self.finger_height, self.finger_clearance = finger_height, finger_clearance
        plant = MultibodyPlant(0.0)
        Parser(plant).AddModels(str(URDF_PATH))
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link"), base_transform(base_xyyaw))
        self.palm = plant.AddFrame(
            FixedOffsetFrame(
                "palm",
                plant.GetFrameByName("tool0"),
                palm_in_flange(),
            )
        )
        plant.Finalize()
        self.frames = ArmFrames(base_xyyaw)
        self.plant = plant
        self.context = plant.CreateDefaultContext()
        self.vmax = max_speed
        self.amax = max_accel

    def palm_pose(self, q) -> RigidTransform:
        self.plant.SetPositions(self.context, np.asarray(q, float))
        return self.plant.CalcRelativeTransform(self.context, self.plant.world_frame(), self.palm)

    def ik(self, position, yaw: float, q_seed, pos_tol: float = 2e-4, rot_tol: float = 2e-3) -> np.ndarray:
        """Joint positions putting the palm at ``position`` with its x axis at ``yaw`` (z up)."""
        ik = InverseKinematics(self.plant, with_joint_limits=True)
        p = np.asarray(position, float)
        ik.AddPositionConstraint(self.palm, np.zeros(3), self.plant.world_frame(), p - pos_tol, p + pos_tol)
        ik.AddOrientationConstraint(
            self.plant.world_frame(), RotationMatrix.MakeZRotation(yaw), self.palm, RotationMatrix(), rot_tol
        )
        q = ik.q()
        prog = ik.get_mutable_prog()
        prog.AddQuadraticErrorCost(np.eye(6), np.asarray(q_seed, float), q)
        prog.SetInitialGuess(q, np.asarray(q_seed, float))
        result = Solve(prog)
        if not result.is_success():
            raise MogError(
                f"no arm configuration reaches the gripper pose {np.round(p, 3).tolist()} "
                f"yaw {np.degrees(yaw):.0f} deg"
            )
        return result.GetSolution(q)

    def vertical(self, xy, z0: float, z1: float, yaw: float, q_seed) -> np.ndarray:
        """IK at ``levels`` heights from z0 to z1 (each seeded by the previous): (levels, 6)."""
        qs, q = [], np.asarray(q_seed, float)
        for z in np.linspace(z0, z1, self.config.levels):
            q = self.ik([xy[0], xy[1], z], yaw, q)
            qs.append(q)
        return np.array(qs)

    def timed(self, waypoints, scale: float = 1.0) -> PathParameterizedTrajectory:
        """A trajectory through joint waypoints (K, 6), at rest at both ends, time-optimal
        under the joint velocity and acceleration limits times ``scale`` (TOPP-RA)."""
        W = np.asarray(waypoints, float)
        if len(W) == 1:
            W = np.vstack([W, W])
        d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(W, axis=0), axis=1))])
        if d[-1] < 1e-6:
            return PathParameterizedTrajectory(
                PiecewisePolynomial.ZeroOrderHold([0.0, 1.0], W[:2].T),
                PiecewisePolynomial.FirstOrderHold([0.0, 1e-3], [[0.0, 1.0]]),
            )
        s = d / d[-1]
        keep = np.concatenate([[True], np.diff(s) > 1e-9])
        s, W = s[keep], W[keep]
        if len(s) <= 2:
            paths = [PiecewisePolynomial.FirstOrderHold(s, W.T)]
        else:
            # The C2 spline is the faster path. Clamped to zero slope at its ends after a long
            # segment and a few short ones (home, above the grasp, down), it bends hard as it
            # comes to rest, and TOPP-RA can fail there ("failed to find the maximum path
            # acceleration at knot 139/146" on two v4 grasps). The shape-preserving cubic
            # does not overshoot its waypoints, and it is solved when the spline is not.
            paths = [
                PiecewisePolynomial.CubicWithContinuousSecondDerivatives(s, W.T, np.zeros(6), np.zeros(6)),
                PiecewisePolynomial.CubicShapePreserving(s, W.T, zero_end_point_derivatives=True),
            ]
        vmax, amax = scale * self.vmax, scale * self.amax
        for i, path in enumerate(paths):
            toppra = Toppra(path, self.plant, Toppra.CalcGridPoints(path, CalcGridPointsOptions()))
            toppra.AddJointVelocityLimit(-vmax * np.ones(6), vmax * np.ones(6))
            toppra.AddJointAccelerationLimit(-amax * np.ones(6), amax * np.ones(6))
            # Drake logs an ERROR when TOPP-RA fails; on every path but the last that failure
            # is the expected way to the fallback, so it is not shown.
            quiet = i < len(paths) - 1
            with drake_log_level(logging.CRITICAL) if quiet else contextlib.nullcontext():
                s_traj = toppra.SolvePathParameterization()
            if s_traj is not None:
                return PathParameterizedTrajectory(path, s_traj)
        raise MogError("TOPP-RA found no time parameterisation for the arm path")

    def _seed(self, q) -> np.ndarray:
        """Where a target's IK starts: the observe pose where known, else ``q``."""
        return np.asarray(q, float) if self.q_home is None else self.q_home

    def bin_ik(self, position, yaw: float, seeds, turn_from=None) -> np.ndarray:
        """The drop pose above the bin. Its yaw is free (the objects fall either way): the
        carry's yaw, turned by a quarter and by a half turn, each from every seed in turn until
        one reaches it (so that one seed in a poor basin of the solver does not end the
        attempt); of those reached, the one that turns the joints least from ``turn_from``
        (default: the first seed), its wrist in band (`wrist_in_band`)."""
        turn_from = np.asarray(seeds[0] if turn_from is None else turn_from, float)
        best = None
        for dyaw in (0.0, np.pi / 2, np.pi):
            for q_seed in seeds:
                try:
                    q = wrist_in_band(self.ik(position, yaw + dyaw, q_seed), self.wrist_center)
                except MogError:
                    continue
                turn = np.abs(q - turn_from).sum()
                if best is None or turn < best[0]:
                    best = (turn, q)
                break  # this yaw's first seed that reaches it
        if best is not None:
            return best[1]  # the yaw that turns the wrist least, in band
        raise MogError(
            f"no arm configuration reaches the drop pose above the bin {np.round(position, 3).tolist()}"
        )

    def _above(self, xy, z: float, yaws, q_start):
        """(yaw, joints) of the pose at ``xy``, height ``z``, among ``yaws``, that turns the
        joints least from ``q_start``, its wrist in band (`wrist_in_band`); None when the arm
        reaches none of them."""
        best = None
        for yaw in yaws:
            try:
                q = wrist_in_band(self.ik([xy[0], xy[1], z], yaw, self._seed(q_start)), self.wrist_center)
            except MogError:
                continue
            if best is None or np.abs(q - q_start).sum() < np.abs(best[1] - q_start).sum():
                best = (yaw, q)
        return best

    def pick_plan(self, grasp, q_start, bin_xy, bin_height: float, q_home=None) -> dict:
        """Joint trajectories of one attempt: start -> above the grasp -> down -> (close) -> up
        -> above the bin -> (open) -> ``q_home`` (default: start). The grasp yaw is taken
        modulo pi, whichever turns the wrist less. Raises MogError for a pose the arm cannot
        reach."""
        cfg = self.config
        z_grasp = self.finger_height + self.finger_clearance
        z_above = z_grasp + cfg.hover
        q_start = np.asarray(q_start, float)
        best = self._above(grasp[:2], z_above, (grasp[2], grasp[2] + np.pi), q_start)
        if best is None:
            raise MogError(
                f"no arm configuration reaches above the grasp at {np.round(grasp[:2], 3).tolist()}"
            )
        yaw, q_above = best
        down = self.vertical(grasp[:2], z_above, z_grasp, yaw, q_above)
        up = self.vertical(grasp[:2], z_grasp, z_grasp + cfg.lift, yaw, down[-1])
        z_bin = bin_height + cfg.bin_clearance + self.finger_height
        seeds = (up[-1], q_start if self.q_home is None else self.q_home)
        q_bin = self.bin_ik([bin_xy[0], bin_xy[1], z_bin], yaw, seeds, turn_from=up[-1])
        approach = self.timed([q_start, q_above, *down[1:]])
        return self._above_table(
            {
                "approach": approach,
                # Where the vertical descent begins: the arm above the grasp, and when.
                "above": q_above,
                "descend_at": passing_time(approach, q_above),
                "lift": self.timed(up, cfg.carry_scale),
                "to_bin": self.timed([up[-1], q_bin], cfg.carry_scale),
                "home": self.timed([q_bin, q_start if q_home is None else np.asarray(q_home, float)]),
                "yaw": yaw,
            }
        )

    def _above_table(self, plan: dict) -> dict:
        """``plan``, once every move of it is found to keep the arm's links LINK_FLOOR over the
        table (sampled every 20 ms); MogError if one would not."""
        for leg, traj in plan.items():
            if not hasattr(traj, "end_time"):
                continue
            for t in np.arange(0.0, traj.end_time() + 0.02, 0.02):
                f = self.frames(traj.value(min(t, traj.end_time())).ravel())
                low = min(LINKS, key=lambda k: f[k][2])
                if f[low][2] < LINK_FLOOR:
                    raise MogError(
                        f"the planned {leg} would take the arm's {low} to {f[low][2]:.3f} m over the "
                        f"table (at least {LINK_FLOOR} m)"
                    )
        return plan

    def retreat(self, q_now, q_above, q_home) -> PathParameterizedTrajectory:
        """Back up the vertical line from ``q_now`` (on a descent) to ``q_above``, then to
        ``q_home``: the way out of a descent stopped on an object (ControllerConfig.guard_force)."""
        return self.timed([q_now, q_above, q_home])

    PUSH_POINTS = 9  # IK points along a push's line

    def push_plan(self, push, q_start, speed: float, q_home=None) -> dict:
        """Joint trajectories of one push (`mog_drake.geometry.push.Push`; the jaws closed):
        start -> above the push's start -> down beside the object -> along the line at a mean
        ``speed`` (m/s) on the cubic ease the physics check simulated (`push_duration`) -> up
        (``push_up``) -> ``q_home`` (default: start; ``push_home``, unless a grasp follows at
        once). The closed
        jaws are square in plan: the wrist takes whichever quarter turn of the push's yaw
        turns it least. Raises MogError for a pose the arm cannot reach."""
        cfg = self.config
        z = self.finger_height + self.finger_clearance
        z_above = z + cfg.hover
        q_start = np.asarray(q_start, float)
        a, b = np.asarray(push.start, float), np.asarray(push.end, float)
        best = self._above(a, z_above, [push.yaw + k * np.pi / 2 for k in range(4)], q_start)
        if best is None:
            raise MogError(f"no arm configuration reaches above the push at {np.round(a, 3).tolist()}")
        yaw, q_above = best
        down = self.vertical(a, z_above, z, yaw, q_above)
        T = push_duration(push, speed)
        times = np.linspace(0.0, T, self.PUSH_POINTS)
        line, q = [], down[-1]
        for t in times:
            s, _ = ease(t / T)
            q = self.ik([*(a + s * (b - a)), z], yaw, q)
            line.append(q)
        along = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
            times, np.array(line).T, np.zeros(6), np.zeros(6)
        )
        up = self.vertical(b, z, z_above, yaw, line[-1])
        return self._above_table(
            {
                "push_approach": self.timed([q_start, q_above, *down[1:]]),
                "push_line": along,
                "push_up": self.timed(up),
                "push_home": self.timed([up[-1], q_start if q_home is None else np.asarray(q_home, float)]),
                "yaw": yaw,
            }
        )
