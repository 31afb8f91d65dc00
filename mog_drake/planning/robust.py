"""Robust grasps (the paper's future work): a grasp is verified only if it lifts its group in
the nominal check and in at least ``required`` of ``samples`` checks of a perturbed world:
every object's perceived pose moved (a shift common to all, the camera's calibration, and one
of each, the fit's), and friction and mass within their ranges, the first sample at the
ends of the ranges that make holding hardest, the others drawn. A Verifier like any
other: the failure memory and the lookahead take its verdicts as they are. No Drake import.

Each perturbation is drawn from the grasp, its group and the poses it is checked at, so the
same check asked again gives the same verdict; the k-th sample's friction and mass are the
k-th variant verifier's own (built once, by the caller), so each keeps its built plants.

Before any physics, a screen of the grasp's geometry at moved poses: in a world whose poses
put an object under the open jaws, or a group object out from between them, the group is
not lifted (the perturbed check would end there too). The grasp is refused without
simulating anything, not even the nominal check, when any of the first ``screen`` worlds is
not clear, or too few of the ``samples`` worlds are to reach ``required``: a grasp whose
jaws may land on an object is not taken, whole or as a partial lift. Only the screen's
worlds keep the jaws as far from every neighbour as the pose error reaches: one world
(``samples: 1``) at level 4 left the guarded arm stopping on a neighbour in 57 of 146
attempts (docs/experiments.md). On the realistic cell 33 of the hardest world's 37
refusals in mog's replayed decisions (tables 0-5) were the screen's (docs/design.md).
Each grasp draws its own worlds, and a refused grasp counts against the grasp planner's cap
on physics checks: where uncertainty screens a group's best candidates, the group ends early
and a smaller one is tried. Screening every candidate in the planner instead, the cap left
to physics, took larger groups that failed more (docs/experiments.md, v33).

Where no robust grasp is left, the picking loop's last resort (`next_pick`) plans with the
nominal check alone: a grasp that lifts at the perceived poses beats leaving the table to a
person. With ``relaxed_share`` it first plans with `RobustVerifier.relaxed`: the screen at that
share of its worlds, then the nominal check.
"""

from __future__ import annotations

import math
import time
import zlib
from dataclasses import replace

import numpy as np

from mog_drake.geometry.conditions import PolygonSet, jaws_clear
from mog_drake.planning.config import RobustConfig
from mog_drake.planning.protocol import GraspResult
from mog_drake.scenes import SceneObject


def perturbation_scales(config: RobustConfig, sample: int, n_objects: int) -> dict:
    """The ``sample``-th variant's friction and mass scales: each object's (per object id),
    the jaws' and the table's. Sample 0 is the world hardest to hold in: every object as
    slippery and heavy as the spreads allow, the jaws' pads as slippery (the table as
    modelled). The others are drawn uniformly within the spreads."""
    f, m = config.friction_spread, config.mass_spread
    if sample == 0:
        return {
            "friction": np.full(n_objects, 1 - f),
            "mass": np.full(n_objects, 1 + m),
            "finger": 1 - f,
            "table": 1.0,
        }
    rng = np.random.default_rng([config.seed, sample, 0xF1C])
    return {
        "friction": rng.uniform(1 - f, 1 + f, n_objects),
        "mass": rng.uniform(1 - m, 1 + m, n_objects),
        "finger": float(rng.uniform(1 - f, 1 + f)),
        "table": float(rng.uniform(1 - f, 1 + f)),
    }


class RobustVerifier:
    """``base``: the nominal check; ``variants``: one verifier per sample, each with its own
    friction and mass (`perturbation_scales`)."""

    def __init__(self, base, variants, config: RobustConfig, *, clear_needed: int | None = None):
        self.base, self.variants, self.config = base, list(variants), config
        self.required = config.required or config.samples
        # Screen worlds that must keep the jaws clear: all of them, but in `relaxed`.
        self.clear_needed = config.screen if clear_needed is None else clear_needed
        if len(self.variants) != config.samples:
            raise ValueError(f"{config.samples} samples need as many variants, got {len(self.variants)}")

    def __getattr__(self, name):  # push(), meshcat, last_build_time ...: the nominal check's
        return getattr(self.base, name)

    def relaxed(self) -> RobustVerifier | None:
        """The last resort's first check (``relaxed_share``): the nominal check after a screen
        that ``relaxed_share`` of the worlds pass; None without it."""
        cfg = self.config
        if not cfg.relaxed_share or not cfg.screen:
            return None
        return RobustVerifier(
            self.base,
            [],
            replace(cfg, samples=0, required=0),
            clear_needed=math.ceil(cfg.relaxed_share * cfg.screen),
        )

    @property
    def nominal(self):
        """The check without perturbations: the last resort's, when no robust grasp is left."""
        return self.base

    def offsets(self, scene, group, grasp, samples) -> np.ndarray:
        """(len(samples), N, 3): each object's move (dx, dy, dtheta) in each listed sample's
        world: a shift common to all (the calibration's) plus the object's own (the fit's),
        drawn from the grasp, its group and the poses, so the same check asked again draws
        the same worlds."""
        cfg = self.config
        key = repr(
            (np.round(grasp, 4).tolist(), sorted(int(i) for i in group), [o.pose for o in scene.objects])
        )
        crc, n = zlib.crc32(key.encode()), len(scene)
        scale = np.array([cfg.pose_sigma, cfg.pose_sigma, cfg.yaw_sigma_deg])
        out = np.empty((len(samples), n, 3))
        for j, k in enumerate(samples):
            z = np.random.default_rng([cfg.seed, k, crc]).standard_normal(2 + 3 * n)
            out[j] = z[2:].reshape(n, 3) * scale
            out[j, :, :2] += cfg.shift_sigma * z[:2]
            out[j, :, 2] = np.radians(out[j, :, 2])
        return out

    def perturbed(self, scene, group, grasp, sample: int):
        """``scene`` with its poses moved for the ``sample``-th check of ``grasp``."""
        return _moved(scene, self.offsets(scene, group, grasp, [sample])[0])

    def clear(self, scene, group, grasp, offsets) -> np.ndarray:
        """(W,) for each world of ``offsets`` (`offsets`): the grasp's open jaws off every
        object and each group object reaching between them (the conditions' collision and
        area checks at its poses), all worlds at once."""
        shapes = [scene.shape(i) for i in range(len(scene))]
        W, K = len(offsets), len(shapes)
        n_max = max((s.sides for s in shapes), default=3)
        local = np.empty((K, n_max, 2))
        for j, shape in enumerate(shapes):
            local[j, : shape.sides], local[j, shape.sides :] = shape.vertices, shape.vertices[-1]
        pose = np.array([o.pose for o in scene.objects]).reshape(K, 3)[None] + offsets
        # As `transform` places each outline, in every world at once.
        c, s = np.cos(pose[..., 2])[..., None], np.sin(pose[..., 2])[..., None]
        vx, vy = local[None, ..., 0], local[None, ..., 1]
        verts = np.stack(
            [c * vx - s * vy + pose[..., 0, None], s * vx + c * vy + pose[..., 1, None]], axis=-1
        )
        polys = PolygonSet(
            vertices=verts.reshape(W * K, n_max, 2),
            counts=np.tile([shape.sides for shape in shapes], W),
            centers=pose[..., :2].reshape(W * K, 2),
            radii=np.tile([shape.radius for shape in shapes], W),
            d_fmin=np.tile([shape.d_fmin for shape in shapes], W),
        )
        return jaws_clear(polys, W, group, grasp, getattr(self.base, "gripper", None))

    def check(self, scene, group, grasp) -> GraspResult:
        t0 = time.perf_counter()
        n_worlds = max(self.config.screen, len(self.variants))
        offsets = self.offsets(scene, group, grasp, range(n_worlds))
        clear = self.clear(scene, group, grasp, offsets).tolist()
        screened = self.config.screen - sum(clear[: self.config.screen])
        short = self.config.screen - screened < self.clear_needed
        if short or sum(clear[: len(self.variants)]) < self.required:
            of = self.config.screen if short else len(self.variants)
            n = screened if short else of - sum(clear[:of])
            return GraspResult(
                False,
                wall_time=time.perf_counter() - t0,
                error=f"not robust: the open jaws start on an object or off the group in {n} of {of} perturbed worlds",
                complete=False,
                not_robust=True,
            )
        first = self.base.check(scene, group, grasp)
        if not first.success or not self.variants:
            return first
        held, lifted = 0, set(first.lifted)
        sim_time, wall_time = first.sim_time, time.perf_counter() - t0
        for k, variant in enumerate(self.variants):
            if not clear[k]:
                lifted, r = set(), GraspResult(False)  # screened: the jaws land on an object
            else:
                r = variant.check(_moved(scene, offsets[k]), group, grasp)
            sim_time, wall_time = sim_time + r.sim_time, wall_time + r.wall_time
            lifted &= set(r.lifted)
            held += bool(r.success)
            if held >= self.required or held + len(self.variants) - k - 1 < self.required:
                break  # the verdict is certain
        ok = held >= self.required
        error = "" if ok else f"not robust: the group lifted in {held} of {k + 1} perturbed checks"
        return replace(
            first,
            success=ok,
            lifted=sorted(lifted),  # what every check run lifted: a part verified robustly too
            sim_time=sim_time,
            wall_time=wall_time,
            error=error,
            not_robust=not ok,
        )


def _moved(scene, offsets):
    """``scene`` with each object moved by its row (dx, dy, dtheta) of ``offsets``."""
    objects = [
        SceneObject(o.shape, o.x + dx, o.y + dy, o.theta + t)
        for o, (dx, dy, t) in zip(scene.objects, offsets)
    ]
    return replace(scene, objects=objects)
