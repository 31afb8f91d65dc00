"""The Perception system: camera images in, a perceived Scene out, once per request.

The application's three systems (`PerceptionSystem`, `PlannerSystem`, `ControllerSystem`) talk
through request counters, so each expensive step runs once per request in a periodic
unrestricted update, and every output only reads state:

    Controller.request (k) -> Perception (perceives once for k) -> scene (k)
    -> Planner (Alg. 1 once for k) -> decision (k) -> Controller (executes, then asks k+1)

None of them reads the plant's ground truth: Perception sees only the camera images.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from mog_drake.perception import Perceiver


class _Immutable:
    """State values that are replaced, never changed in place. Drake copies abstract state
    (every unrestricted update copies the whole state); a deep copy of a perceived Scene or a
    motion plan per 10 ms tick cost a third of a pick run's wall time, so copies share."""

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self


@dataclass
class Perceived(_Immutable):
    counter: int = -1
    scene: object = None


class PerceptionSystem(LeafSystem):
    """camera.rgb_image, camera.depth_image, request -> scene (a perceived Scene).
    ``X_WC``: the camera's pose (4x4); ``K``: its intrinsics (fx, fy, cx, cy);
    ``perceiver``: what turns the images into a scene (e.g. `Scenario.perceiver`)."""

    def __init__(self, X_WC, K, perceiver: Perceiver, period: float = 0.01):
        super().__init__()
        self._perceiver = perceiver
        self._X_WC = np.asarray(X_WC, float)
        self._K = tuple(float(v) for v in K)
        self._rgb = self.DeclareAbstractInputPort("camera.rgb_image", AbstractValue.Make(ImageRgba8U()))
        self._depth = self.DeclareAbstractInputPort("camera.depth_image", AbstractValue.Make(ImageDepth32F()))
        self._request = self.DeclareVectorInputPort("request", 1)
        self._state = self.DeclareAbstractState(AbstractValue.Make(Perceived()))
        self.DeclareAbstractOutputPort(
            "scene",
            lambda: AbstractValue.Make(Perceived()),
            self._out,
            prerequisites_of_calc={self.all_state_ticket()},
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)

    def _update(self, context, state) -> None:
        req = int(self._request.Eval(context)[0])
        cur = context.get_abstract_state(self._state).get_value()
        if req <= cur.counter:
            return
        rgb = self._rgb.Eval(context).data
        depth = self._depth.Eval(context).data[:, :, 0]
        scene = self._perceiver.perceive(rgb, depth, self._X_WC, self._K, seed=req)
        state.get_mutable_abstract_state(self._state).set_value(Perceived(req, scene))

    def _out(self, context, output) -> None:
        output.set_value(context.get_abstract_state(self._state).get_value())
