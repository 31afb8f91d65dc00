"""The Perception system: camera images in, a perceived Scene out, once per request.

The application's three systems (`PerceptionSystem`, `PlannerSystem`, `ControllerSystem`) talk
through request counters, so each expensive step runs once per request, as a job off the
Diagram's thread (`mog_drake.systems.jobs`), and every output only reads state:

    Controller.request (k) -> Perception (perceives once for k) -> scene (k)
    -> Planner (Alg. 1 once for k) -> decision (k) -> Controller (executes k; asks k+1 as
    soon as the arm is out of the camera's view, and checks at the observe pose that the
    table has not changed since that image: if it has, it asks k+2 and k+1 is dropped)

None of them reads the plant's ground truth: Perception sees only the camera images.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from mog_drake.config import LatencyConfig
from mog_drake.perception import Perceiver
from mog_drake.systems.jobs import Worker, clock_of
from mog_drake.systems.messages import Checked, Perceived, Slot


class PerceptionSystem(LeafSystem):
    """camera.rgb_image, camera.depth_image, request, check -> scene (`Perceived`), checked
    (`Checked`).

    A new ``request`` counter starts a perception job on a worker thread (`Worker`) once the
    table is at rest (two frames ``still_dt`` apart agree as the change check asks; at most
    ``still_max`` s of waiting), with the images of that moment; the job's scene becomes
    visible after its latency (`LatencyConfig`).
    A ``check`` of a perceived counter compares the depth image now with the one it was
    perceived from, over the perceived table: the table changed if more than
    ``change_pixels`` pixels moved by more than ``change_depth`` m (an object dropped in
    transit, or one moved by the lift). ``X_WC``: the camera's pose (4x4); ``K``: its
    intrinsics (fx, fy, cx, cy); ``perceiver``: what turns the images into a scene (e.g.
    `Scenario.perceiver`). ``block``: a collecting event may wait for a running job (see
    `mog_drake.systems.jobs`; False on hardware)."""

    def __init__(
        self,
        X_WC,
        K,
        perceiver: Perceiver,
        period: float = 0.01,
        latency: LatencyConfig | None = None,
        block: bool = True,
        *,
        change_pixels: int = 40,
        change_depth: float = 0.004,
        still_dt: float = 0.1,
        still_max: float = 3.0,
    ):
        super().__init__()
        self._perceiver = perceiver
        self._X_WC = np.asarray(X_WC, float)
        self._K = tuple(float(v) for v in K)
        latency = latency or LatencyConfig()
        self._latency = latency.of("perception")
        self._block = block
        self._change = (change_pixels, change_depth)
        self._still = (still_dt, still_max)
        self._worker = Worker("perception", clock_of(latency))
        self._rgb = self.DeclareAbstractInputPort("camera.rgb_image", AbstractValue.Make(ImageRgba8U()))
        self._depth = self.DeclareAbstractInputPort("camera.depth_image", AbstractValue.Make(ImageDepth32F()))
        self._request = self.DeclareVectorInputPort("request", 1)
        self._check = self.DeclareVectorInputPort("check", 1)
        self._state = self.DeclareAbstractState(AbstractValue.Make(Perceived()))
        self._job = self.DeclareAbstractState(AbstractValue.Make(Slot()))
        self._checked = self.DeclareAbstractState(AbstractValue.Make(Checked()))
        only_state = {self.all_state_ticket()}
        self.DeclareAbstractOutputPort(
            "scene", lambda: AbstractValue.Make(Perceived()), self._out, prerequisites_of_calc=only_state
        )
        self.DeclareAbstractOutputPort(
            "checked",
            lambda: AbstractValue.Make(Checked()),
            lambda c, o: o.set_value(c.get_abstract_state(self._checked).get_value()),
            prerequisites_of_calc=only_state,
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)

    def shutdown(self) -> None:
        self._worker.shutdown()

    def wall_total(self, context) -> float:
        """Wall time of the perception jobs whose scenes became visible (s)."""
        return context.get_abstract_state(self._state).get_value().wall_total

    def _update(self, context, state) -> None:
        t = context.get_time()
        req = int(self._request.Eval(context)[0])
        cur = context.get_abstract_state(self._state).get_value()
        slot = context.get_abstract_state(self._job).get_value()
        checked = context.get_abstract_state(self._checked).get_value()
        job = slot.job
        if job is not None and job.visible(t, self._latency, self._block):
            scene = job.result()
            state.get_mutable_abstract_state(self._state).set_value(
                Perceived(
                    job.counter,
                    scene,
                    job.t_request,
                    t,
                    job.wall_time(),
                    job.info["retake"],
                    job.info["depth"],
                    cur.wall_total + job.wall_time(),
                )
            )
            state.get_mutable_abstract_state(self._job).set_value(Slot())
            job = None
        last = job.counter if job is not None else cur.counter
        if job is None and req > max(last, 0):  # requests count from 1
            # The table at rest first: a frame `still_dt` after the last one that differs from
            # it no more than the change check allows (an object pushed by the grasp may still
            # be sliding or rocking when the arm has left it). After `still_max` s, go on.
            # Rendered only at those moments: a frame costs milliseconds of CPU.
            pending = slot.pending
            if pending is not None and pending[0] == req and t - pending[2] < self._still[0] - 1e-9:
                return
            depth = np.array(self._depth.Eval(context).data[:, :, 0])  # copies: jobs outlive events
            if pending is None or pending[0] != req:
                state.get_mutable_abstract_state(self._job).set_value(Slot(pending=(req, depth, t, t)))
                return
            _, depth0, t0, t_first = pending
            n = self._perceiver.changed_pixels(
                depth0, depth, self._X_WC, self._K, self._change[1], still=True
            )
            if n > self._change[0] and t - t_first < self._still[1]:
                state.get_mutable_abstract_state(self._job).set_value(Slot(pending=(req, depth, t, t_first)))
                return
            rgb = np.array(self._rgb.Eval(context).data)
            # A retake: the request after a check that found the table changed.
            retake = checked.changed and checked.counter == req - 1
            job = self._worker.submit(
                self._perceiver.perceive,
                rgb,
                depth,
                self._X_WC,
                self._K,
                req,
                t_request=t,
                counter=req,
                info={"depth": depth, "retake": retake},
            )
            state.get_mutable_abstract_state(self._job).set_value(Slot(job))
        chk = int(self._check.Eval(context)[0])
        if chk > checked.counter and cur.counter == chk and cur.depth is not None:
            now = np.asarray(self._depth.Eval(context).data[:, :, 0])
            n = self._perceiver.changed_pixels(cur.depth, now, self._X_WC, self._K, self._change[1])
            state.get_mutable_abstract_state(self._checked).set_value(Checked(chk, n > self._change[0], n))

    def _out(self, context, output) -> None:
        output.set_value(context.get_abstract_state(self._state).get_value())
