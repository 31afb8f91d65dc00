"""Benchmarks that print tables. Speed is shown here, never asserted in tests."""

from __future__ import annotations

import time
from functools import partial

import numpy as np

from mog_drake.errors import MogError
from mog_drake.geometry import GripperGeometry, evaluate_grasps, gen_grasp_cands, rank_grasp_cands
from mog_drake.scenes import row_scene


def _timed(fn, repeats: int):
    best = []
    out = None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        best.append(time.perf_counter() - t)
    return float(np.median(best)), out


def _filter_rank(polys, group, cands, gripper):
    ev = evaluate_grasps(polys, group, cands, gripper)
    order = rank_grasp_cands(ev)
    return order[ev.passed[order]]


def bench_geometry(
    scenes_per_class: int = 20,
    seed: int = 0,
    repeats: int = 5,
    classes=range(2, 8),
    gripper: GripperGeometry | None = None,
) -> list[dict]:
    """Median time per scene of candidate generation (Np x Ntheta grasps + jaw collision
    rejection), of filtering + ranking (h0, A_i, both conditions, sort by A_T) and in total,
    for the paper's row classes. Each scene's figure is the median of ``repeats`` runs."""
    gripper = gripper or GripperGeometry()
    rows = []
    for c in classes:
        gen_t, fil_t, n_cands = [], [], []
        for k in range(scenes_per_class):
            scene = row_scene(c, np.random.default_rng([seed, c, k]))
            polys = scene.polygons()
            tg, cands = _timed(partial(gen_grasp_cands, polys, scene.group, gripper), repeats)
            tf, _ = _timed(partial(_filter_rank, polys, scene.group, cands, gripper), repeats)
            gen_t.append(tg)
            fil_t.append(tf)
            n_cands.append(len(cands))
        tot = np.array(gen_t) + np.array(fil_t)
        rows.append(
            {
                "objects": c,
                "scenes": scenes_per_class,
                "candidates": float(np.mean(n_cands)),
                "generate_ms": 1e3 * float(np.median(gen_t)),
                "filter_rank_ms": 1e3 * float(np.median(fil_t)),
                "total_ms": 1e3 * float(np.median(tot)),
                "total_max_ms": 1e3 * float(np.max(tot)),
            }
        )
    return rows


def bench_verifier(
    seeds: int = 5, seed: int = 0, classes=range(1, 8), warm_checks: int = 3, config=None
) -> list[dict]:
    """Wall time of one physics check per group size, median over seeds: ``cold`` builds the
    plant and simulates (a fresh verifier), ``warm`` reuses the plant of the same group (what
    a planner pays for its second and later candidates). Candidates are the top-ranked
    collision-free grasps of each seeded row scene."""
    from mog_drake.sim.verifier import DrakeVerifier

    rows = []
    for c in classes:
        cold, warm, sim_t, succ, n = [], [], [], 0, 0
        for k in range(seeds):
            scene = row_scene(c, np.random.default_rng([seed, c, k]))
            polys = scene.polygons()
            cands = gen_grasp_cands(polys, scene.group)
            if len(cands) == 0:
                continue
            ev = evaluate_grasps(polys, scene.group, cands)
            order = rank_grasp_cands(ev)
            v = DrakeVerifier(config)
            r = v.check(scene, scene.group, cands[order[0]])
            cold.append(r.wall_time)
            sim_t.append(r.sim_time)
            succ += r.success
            n += 1
            for i in order[1 : 1 + warm_checks]:
                r = v.check(scene, scene.group, cands[i])
                warm.append(r.wall_time)
                succ += r.success
                n += 1
        rows.append(
            {
                "objects": c,
                "checks": n,
                "cold_median_s": float(np.median(cold)) if cold else float("nan"),
                "warm_median_s": float(np.median(warm)) if warm else float("nan"),
                "warm_max_s": float(np.max(warm)) if warm else float("nan"),
                "sim_time_s": float(np.median(sim_t)) if sim_t else float("nan"),
                "lifted_share": succ / n if n else float("nan"),
            }
        )
    return rows


def bench_agreement(n_candidates: int = 60, seed: int = 0, fine_dt: float = 0.0005, progress=None) -> dict:
    """Outcome agreement between the default dt = 5 ms verifier and a fine reference.

    Half of the candidates are drawn uniformly from the collision-free candidates of random
    row scenes (classes 2..7), half from those that pass both conditions (the ones a planner
    actually simulates, and the harder calls). Returns the confusion counts and the list of
    disagreements (scene class, seed, grasp) so each can be replayed."""

    from mog_drake.sim.models import with_time_step
    from mog_drake.sim.verifier import DrakeVerifier, VerifierConfig

    base = VerifierConfig()
    fine_cfg = VerifierConfig(contact=with_time_step(base.contact, fine_dt))
    coarse, fine = DrakeVerifier(base), DrakeVerifier(fine_cfg)
    rng = np.random.default_rng(seed)
    counts = {"both_success": 0, "both_failure": 0, "coarse_only": 0, "fine_only": 0}
    disagreements, coarse_t, fine_t, errors = [], [], [], 0
    done = 0
    while done < n_candidates:
        c = int(rng.integers(2, 8))
        scene_seed = int(rng.integers(1 << 31))
        scene = row_scene(c, np.random.default_rng(scene_seed))
        polys = scene.polygons()
        cands = gen_grasp_cands(polys, scene.group)
        if len(cands) == 0:
            continue
        ev = evaluate_grasps(polys, scene.group, cands)
        pool = np.flatnonzero(ev.passed) if done % 2 else np.arange(len(cands))
        if len(pool) == 0:
            continue
        g = cands[int(rng.choice(pool))]
        a = coarse.check(scene, scene.group, g)
        b = fine.check(scene, scene.group, g)
        coarse_t.append(a.wall_time)
        fine_t.append(b.wall_time)
        errors += bool(a.error) + bool(b.error)
        key = {
            (True, True): "both_success",
            (False, False): "both_failure",
            (True, False): "coarse_only",
            (False, True): "fine_only",
        }[(a.success, b.success)]
        counts[key] += 1
        if a.success != b.success:
            disagreements.append(
                {
                    "class": c,
                    "scene_seed": scene_seed,
                    "grasp": g.tolist(),
                    "coarse": a.to_dict(),
                    "fine": b.to_dict(),
                }
            )
        done += 1
        if progress:
            progress(done, n_candidates)
    n = sum(counts.values())
    return {
        "candidates": n,
        "fine_dt": fine_dt,
        "coarse_dt": base.contact.plant.time_step,
        **counts,
        "agreement": (counts["both_success"] + counts["both_failure"]) / n,
        "coarse_median_s": float(np.median(coarse_t)),
        "fine_median_s": float(np.median(fine_t)),
        "results_with_error": errors,
        "disagreements": disagreements,
    }


def bench_perception(tables: int = 5, seed: int = 0, toppled: int = 0) -> list[dict]:
    """Perception accuracy on rendered cluttered isrr33 tables (seeds seed .. seed+tables-1):
    objects found, missed and extra, median and worst position (mm) and yaw error (deg, modulo
    the shape's symmetry), and time per image. ``toppled`` bars per table are laid on their
    side before rendering (the pose a knocked-over bar takes)."""
    from mog_drake.perception import pose_errors
    from mog_drake.scenario import ClutteredScene, Scenario, camera_intrinsics, camera_pose
    from mog_drake.scenes import Scene, SceneObject, cluttered_scene, default_library
    from mog_drake.station import MakeStation, render_still

    rows = []
    for k in range(seed, seed + tables):
        scene = cluttered_scene(np.random.default_rng(k))
        laid = 0
        for i, o in enumerate(scene.objects):
            if laid >= toppled or o.shape not in ("thin_bar", "thick_bar"):
                continue
            objs = list(scene.objects)
            objs[i] = SceneObject(f"{o.shape}:on_side", o.x, o.y, o.theta)
            try:  # a toppled bar's wider footprint must not overlap a neighbour
                scene = Scene(objs, default_library(), table=scene.table).validate()
                laid += 1
            except MogError:
                pass
        sc = Scenario(scene=ClutteredScene(seed=k))
        d, h = MakeStation(sc, scene)
        rgb, depth = render_still(sc, d)
        t = time.perf_counter()
        seen = sc.perceiver().perceive(rgb, depth, camera_pose(sc.camera), camera_intrinsics(sc.camera))
        dt = time.perf_counter() - t
        errs = pose_errors(seen, h.scene)
        found = [e for e in errs if e["object"] is not None and e["position"] is not None]
        pos = 1e3 * np.array([e["position"] for e in found])
        yaw = np.degrees([e["yaw"] for e in found])
        rows.append(
            {
                "table_seed": k,
                "objects": len(h.scene),
                "toppled": laid,
                "found": len(found),
                "missed": sum(e["object"] is not None and e["position"] is None for e in errs),
                "extra": sum(bool(e.get("extra")) for e in errs),
                "unrecognised": seen.meta["unrecognised_blobs"],
                "pos_median_mm": float(np.median(pos)) if len(pos) else float("nan"),
                "pos_max_mm": float(pos.max()) if len(pos) else float("nan"),
                "yaw_median_deg": float(np.median(yaw)) if len(yaw) else float("nan"),
                "yaw_max_deg": float(yaw.max()) if len(yaw) else float("nan"),
                "time_s": dt,
            }
        )
    return rows


def bench_station(seed: int = 0, sim_seconds: float = 1.0) -> list[dict]:
    """CPU seconds per simulated second of the simulated station (arm still at its observe
    pose, jaws open) with a whole isrr33 table in three states: every object on the table;
    every object piled in the bin; and the pile retired (`BinRetirement`)."""
    from pydrake.math import RigidTransform
    from pydrake.multibody.math import SpatialVelocity
    from pydrake.systems.analysis import Simulator

    from mog_drake.scenario import ClutteredScene, Scenario
    from mog_drake.station import MakeStation, hold_still
    from mog_drake.station.scoring import BinRetirement

    sc = Scenario(scene=ClutteredScene(seed=seed))
    d, h = MakeStation(sc)
    sim = Simulator(d)
    ctx = sim.get_mutable_context()
    hold_still(sc, d, ctx)
    pc = h.plant.GetMyMutableContextFromRoot(ctx)
    sim.Initialize()
    sim.AdvanceTo(0.3)

    def cost(**extra) -> dict:
        t0, s0 = time.process_time(), ctx.get_time()
        while ctx.get_time() < s0 + sim_seconds - 1e-9:
            sim.AdvanceTo(min(ctx.get_time() + 0.25, s0 + sim_seconds))
            if retire is not None:
                retire.update(pc)
        return {
            **extra,
            "objects": len(h.bodies),
            "cpu_s_per_sim_s": (time.process_time() - t0) / sim_seconds,
        }

    retire = None
    rows = [cost(state="on the table")]
    rng = np.random.default_rng(seed)
    cx, cy = sc.bin.center
    for k, body in enumerate(h.bodies.values()):  # dropped in, one above the other
        xy = [cx + rng.uniform(-0.08, 0.08), cy + rng.uniform(-0.05, 0.05)]
        h.plant.SetFreeBodyPose(pc, body, RigidTransform([*xy, 0.02 + 0.035 * k]))
        h.plant.SetFreeBodySpatialVelocity(pc, body, SpatialVelocity.Zero())
    sim.AdvanceTo(ctx.get_time() + 3.0)  # the pile settles
    rows.append(cost(state="piled in the bin"))
    retire = BinRetirement(h.plant, h.bodies, sc)
    retire.update(pc)
    rows.append(cost(state="piled, then retired"))
    return rows


def bench_replanning(tables: int = 1, seed: int = 0, progress=None) -> list[dict]:
    """Planning time of one table's decisions, replayed without the robot: on each seeded
    isrr33 table (the scene seeds of ``eval picking --seed``), plan, remove the objects the
    physics check lifted, plan again until the table is empty. "before": every group planned
    afresh before each decision and every partial lift reported; "after": the picking
    defaults (failed groups remembered, partial lifts of two or more)."""
    from dataclasses import replace

    from mog_drake.planning.picking import next_pick
    from mog_drake.scenario import ClutteredScene, Scenario
    from mog_drake.scenes import Scene
    from mog_drake.sim.verifier import DrakeVerifier
    from mog_drake.station import scene_from_spec
    from mog_drake.systems.pick import make_planner

    rows, done = [], 0
    for k in range(tables):
        table_seed = seed * 1_000_000 + k
        for setting in ("before", "after"):
            planner = make_planner(Scenario())
            if setting == "before":
                planner.verifier = DrakeVerifier(replace(planner.verifier.config, report_partial_lifts=1))
            scene = scene_from_spec(ClutteredScene(seed=table_seed))
            rng, failures = np.random.default_rng(table_seed), () if setting == "after" else None
            n0, decisions, checks, remembered, planning = len(scene), 0, 0, 0, 0.0
            while len(scene) and decisions < 3 * n0:
                d = next_pick(scene, planner, rng=rng, failures=failures)
                failures = d.failures if failures is not None else None
                decisions += 1
                checks += d.physics_checks
                remembered += d.remembered
                planning += d.planning_time
                if d.status != "grasp":
                    break
                gone = set(d.expected) or set(d.group)
                scene = Scene(
                    [o for i, o in enumerate(scene.objects) if i not in gone], scene.library, scene.table
                )
            rows.append(
                {
                    "table_seed": table_seed,
                    "setting": setting,
                    "decisions": decisions,
                    "objects_left": len(scene),
                    "physics_checks": checks,
                    "groups_remembered": remembered,
                    "planning_s": round(planning, 1),
                    "per_decision_s": round(planning / max(decisions, 1), 2),
                }
            )
            done += 1
            if progress:
                progress(done, 2 * tables)
    return rows


def hold_verifiers(window: float):
    """The built-in scenario's picking planner, and the two physics checks `bench_hold`
    compares: its own settings with the whole hold simulated, and the same ending the hold
    once settled for ``window`` seconds."""
    from dataclasses import replace

    from mog_drake.scenario import Scenario
    from mog_drake.sim.verifier import DrakeVerifier
    from mog_drake.systems.pick import make_planner

    if window <= 0:
        raise MogError(f"hold bench: window must be > 0 s, got {window}")
    planner = make_planner(Scenario())
    # The reference holds the whole hold, whatever the built-in scenario's settle window.
    ref = DrakeVerifier(replace(planner.verifier.config, settle_window=0.0), planner.verifier.gripper)
    fast = DrakeVerifier(replace(ref.config, settle_window=window), ref.gripper)
    return planner, ref, fast


def bench_hold(tables: int = 5, seed: int = 0, window: float = 0.5, progress=None) -> dict:
    """The picking's physics check with and without ending the hold once every object has
    settled (``VerifierConfig.settle_window``), on the grasps the picking planner checks.

    Per cluttered isrr33 table (seeds seed .. seed+tables-1): its first four multi-object
    groups and four random lone objects, each planned as the picking planner plans it (the
    built-in scenario: up to 4 physics checks, stopping at a success); every checked grasp is
    checked again with the settled-hold exit. Then a bar laid on its side, alone, gripped
    along 4 random axes from end to end to across (a grip that lifts and later slips).
    Returns per kind (multi, lone, on_side) the checks, successes, verdicts that differ
    (success or lifted objects), and mean wall and simulated seconds of each; and the
    differing checks, to replay."""
    from mog_drake.geometry import ranked_groups
    from mog_drake.scenes import Scene, SceneObject, cluttered_scene

    planner, ref, fast = hold_verifiers(window)
    log: list[dict] = []

    class _Both:
        kind = ""

        def check(self, scene, group, grasp):
            a = ref.check(scene, group, grasp)
            b = fast.check(scene, group, grasp)
            log.append(
                {
                    "kind": self.kind,
                    "scene": scene,
                    "group": list(group),
                    "grasp": list(grasp),
                    "a": a,
                    "b": b,
                }
            )
            return a

    both = _Both()
    planner.verifier = both
    rng = np.random.default_rng(seed)
    for k in range(seed, seed + tables):
        scene = cluttered_scene(np.random.default_rng(k))
        polys = scene.polygons()
        ranked = ranked_groups(polys, planner.gripper)
        multi = [g for g in ranked if len(g) > 1][:4]
        lone = [(int(i),) for i in rng.choice(len(scene), 4, replace=False)]
        for kind, groups in (("multi", multi), ("lone", lone)):
            both.kind = kind
            for g in groups:
                planner.plan(scene, g)
        both.kind = "on_side"
        bar = str(rng.choice(["thin_bar", "thick_bar"]))
        yaw = float(rng.uniform(-np.pi, np.pi))
        side = Scene([SceneObject(f"{bar}:on_side", 0.0, 0.0, yaw)], scene.library)
        for turn in rng.uniform(0, np.pi / 2, 4):
            both.check(side, [0], (0.0, 0.0, yaw + turn))
        if progress:
            progress(k - seed + 1, tables)

    def same(a, b) -> bool:
        return a.success == b.success and (not a.complete or sorted(a.lifted) == sorted(b.lifted))

    rows = []
    for kind in ("multi", "lone", "on_side"):
        got = [r for r in log if r["kind"] == kind]
        if not got:
            continue
        rows.append(
            {
                "kind": kind,
                "checks": len(got),
                "successes": sum(r["a"].success for r in got),
                "differ": sum(not same(r["a"], r["b"]) for r in got),
                "wall_s": float(np.mean([r["a"].wall_time for r in got])),
                "wall_settled_s": float(np.mean([r["b"].wall_time for r in got])),
                "sim_s": float(np.mean([r["a"].sim_time for r in got])),
                "sim_settled_s": float(np.mean([r["b"].sim_time for r in got])),
            }
        )
    differ = [
        {
            "kind": r["kind"],
            "scene": r["scene"].to_dict(),
            "group": r["group"],
            "grasp": [float(v) for v in r["grasp"]],
            "full_hold": r["a"].to_dict(),
            "settled": r["b"].to_dict(),
        }
        for r in log
        if not same(r["a"], r["b"])
    ]
    wall = sum(r["a"].wall_time for r in log), sum(r["b"].wall_time for r in log)
    return {
        "tables": tables,
        "seed": seed,
        "window_s": window,
        "settle_speed_m_s": fast.config.settle_speed,
        "rows": rows,
        "wall_s": wall[0],
        "wall_settled_s": wall[1],
        "differing": differ,
    }
