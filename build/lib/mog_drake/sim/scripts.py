"""The physics check's gantry scripts: the desired gantry and finger states over time for a
grasp (close, lift, hold) and for a push, as LeafSystems."""

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from mog_drake.geometry import GripperGeometry
from mog_drake.geometry.push import ease as _smooth
from mog_drake.sim.models import (
    GripperPhysics,
)
from mog_drake.sim.verifier_config import VerifierConfig


class GraspScript(LeafSystem):
    """Desired gantry and finger states over time for one grasp u = (x, y, theta) (a numeric
    parameter): hold open at u, close the jaws at constant speed, squeeze, lift, hold."""

    def __init__(self, gripper: GripperGeometry, config: VerifierConfig, physics: GripperPhysics):
        super().__init__()
        self._g = gripper
        self._cfg = config
        self._v = physics.close_speed
        self._tl = config.timeline(gripper, physics)
        self._z0 = physics.finger_height + physics.finger_clearance
        self._grasp_index = self.DeclareNumericParameter(BasicVector(np.zeros(3)))
        self.DeclareVectorOutputPort("desired_state", 12, self._calc)

    @property
    def z_grasp(self) -> float:
        return self._z0

    def set_grasp(self, context, grasp) -> None:
        context.get_mutable_numeric_parameter(self._grasp_index).SetFromVector(np.asarray(grasp, dtype=float))

    def _calc(self, context, output) -> None:
        t = context.get_time()
        x, y, th = context.get_numeric_parameter(self._grasp_index).value()
        tl, g = self._tl, self._g
        half_open, half_closed = g.opening / 2, g.plate_thickness / 2
        v = self._v
        if t < tl["close0"]:
            f, fd = half_open, 0.0
        elif t < tl["close1"]:
            f, fd = half_open - v * (t - tl["close0"]), -v
        else:
            f, fd = half_closed, 0.0
        dur = tl["lift1"] - tl["lift0"]
        s, sd = _smooth((t - tl["lift0"]) / dur)
        z = self._z0 + s * self._cfg.lift_height
        zd = sd * self._cfg.lift_height / dur if tl["lift0"] <= t <= tl["lift1"] else 0.0
        output.SetFromVector([x, y, z, th, -f, f, 0.0, 0.0, zd, 0.0, -fd, fd])


class PushScript(LeafSystem):
    """Desired gantry and finger states for one push (`mog_drake.geometry.push.Push`, set as a
    numeric parameter): the closed jaws at grasp height move from the push's start to its
    end along a cubic ease over ``duration``, then stay."""

    def __init__(self, gripper: GripperGeometry, config: VerifierConfig, physics: GripperPhysics):
        super().__init__()
        self._g = gripper
        self._z0 = physics.finger_height + physics.finger_clearance
        # x0, y0, x1, y1, yaw, duration
        self._index = self.DeclareNumericParameter(BasicVector(np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])))
        self.DeclareVectorOutputPort("desired_state", 12, self._calc)

    @property
    def z_grasp(self) -> float:
        return self._z0

    def set_push(self, context, push, duration: float) -> None:
        context.get_mutable_numeric_parameter(self._index).SetFromVector(
            [*push.start, *push.end, push.yaw, duration]
        )

    def _calc(self, context, output) -> None:
        x0, y0, x1, y1, yaw, T = context.get_numeric_parameter(self._index).value()
        s, sd = _smooth(context.get_time() / T)
        sd = sd / T if context.get_time() <= T else 0.0
        f = self._g.plate_thickness / 2
        x, y = x0 + s * (x1 - x0), y0 + s * (y1 - y0)
        output.SetFromVector([x, y, self._z0, yaw, -f, f, sd * (x1 - x0), sd * (y1 - y0), 0.0, 0.0, 0.0, 0.0])
