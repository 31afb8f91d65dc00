"""The physics check: its speed, its agreement with a finer time step, and the settled hold."""

from __future__ import annotations

import time

import numpy as np

from mog_drake.errors import MogError
from mog_drake.geometry import evaluate_grasps, gen_grasp_cands, rank_grasp_cands
from mog_drake.scenes import row_scene


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


def agreement_text(doc: dict) -> str:
    from mog_drake.tables import format_table

    summary = {k: v for k, v in doc.items() if k != "disagreements"}
    return format_table([summary]) + "".join(
        f"\n  disagreement: class {d['class']} scene seed {d['scene_seed']} grasp "
        f"{[round(x, 5) for x in d['grasp']]}: 5 ms {d['coarse']['success']} ({d['coarse']['error'] or 'ok'}), "
        f"fine {d['fine']['success']} ({d['fine']['error'] or 'ok'})"
        for d in doc["disagreements"]
    )


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


def _replay_checks(planner, ref, fast, tables: int, seed: int, progress=None) -> list[dict]:
    """Every physics check the picking planner makes on seeded tables, made by two checks:
    ``ref`` (whose verdict the planner goes on with) and ``fast``. Per cluttered isrr33 table
    (seeds seed .. seed+tables-1): its first four multi-object groups and four random lone
    objects, each planned as the picking planner plans it (up to 4 physics checks, stopping
    at a success); then a bar laid on its side, alone, gripped along 4 random axes from end to
    end to across (a grip that lifts and later slips). Returns one record per check: kind
    (multi, lone, on_side), scene, group, grasp, and both results (a: ref, b: fast)."""
    from mog_drake.geometry import ranked_groups
    from mog_drake.scenes import Scene, SceneObject, cluttered_scene

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
                    "bodies": (len(ref._sim.bodies), len(fast._sim.bodies)),
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
    return log


def _same(a, b) -> bool:
    """The same verdict: success, and (for a check that ran to its end) the objects lifted."""
    return a.success == b.success and (not a.complete or sorted(a.lifted) == sorted(b.lifted))


def _differing(log: list[dict], a: str, b: str) -> list[dict]:
    """The checks of ``log`` whose two verdicts differ, to replay: each with its scene, group,
    grasp and both results (named ``a`` and ``b``)."""
    return [
        {
            "kind": r["kind"],
            "scene": r["scene"].to_dict(),
            "group": r["group"],
            "grasp": [float(v) for v in r["grasp"]],
            a: r["a"].to_dict(),
            b: r["b"].to_dict(),
        }
        for r in log
        if not _same(r["a"], r["b"])
    ]


def bench_hold(tables: int = 5, seed: int = 0, window: float = 0.5, progress=None) -> dict:
    """The picking's physics check with and without ending the hold once every object has
    settled (``VerifierConfig.settle_window``), on the grasps the picking planner checks
    (`_replay_checks`). Returns per kind (multi, lone, on_side) the checks, successes,
    verdicts that differ (success or lifted objects), and mean wall and simulated seconds of
    each; and the differing checks, to replay."""
    planner, ref, fast = hold_verifiers(window)
    log = _replay_checks(planner, ref, fast, tables, seed, progress)
    same = _same
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
    differ = _differing(log, "full_hold", "settled")
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


# The verifier settings `bench bodies`, `bench table` and `bench surface` compare: (name,
# path of the setting in VerifierConfig, value) for the reference check (whose verdicts the
# planner goes on with) and the other one.
PAIRS = {
    "bodies": (("group_bodies", "bodies", "group"), ("grasp_bodies", "bodies", "grasp")),
    "table": (
        ("halfspace", "contact.table_collision", "halfspace"),
        ("box", "contact.table_collision", "box"),
    ),
    "surface": (
        ("polygon", "contact.plant.contact_surface_representation", "polygon"),
        ("triangle", "contact.plant.contact_surface_representation", "triangle"),
    ),
}


def with_setting(config, path: str, value):
    """A copy of ``config`` with the setting at dotted ``path`` set to ``value``; the
    configs on the way are copied, never changed (Drake's own are no dataclasses)."""
    import copy
    import dataclasses

    head, _, rest = path.partition(".")
    if rest:
        value = with_setting(getattr(config, head), rest, value)
    if dataclasses.is_dataclass(config):
        return dataclasses.replace(config, **{head: value})
    new = copy.copy(config)
    setattr(new, head, value)
    return new


def bench_pair(what: str, tables: int = 5, seed: int = 0, progress=None) -> dict:
    """The picking's physics check with two settings (``PAIRS[what]``) on the grasps the
    picking planner checks (`_replay_checks`). "bodies": simulating every object any grasp of
    the group can reach (``VerifierConfig.bodies`` "group") or only what this grasp can touch
    ("grasp"). "table": the table's collision geometry a half-space or a box
    (``ContactConfig.table_collision``). "surface": hydroelastic contact surfaces as
    polygons or triangles (``ContactConfig.plant.contact_surface_representation``). Returns
    per kind (multi, lone, on_side) the checks, successes each way, verdicts that differ
    (success or lifted objects), mean bodies simulated, and mean CPU seconds each way; the CPU
    seconds of all checks; and the differing checks, to replay."""
    from mog_drake.scenario import Scenario
    from mog_drake.sim.verifier import DrakeVerifier
    from mog_drake.systems.pick import make_planner

    (a, path_a, value_a), (b, path_b, value_b) = PAIRS[what]
    planner = make_planner(Scenario())
    base = planner.verifier.config
    ref = _Timed(DrakeVerifier(with_setting(base, path_a, value_a), planner.verifier.gripper))
    other = _Timed(DrakeVerifier(with_setting(base, path_b, value_b), planner.verifier.gripper))
    log = _replay_checks(planner, ref, other, tables, seed, progress)
    rows = []
    for kind in ("multi", "lone", "on_side"):
        got = [r for r in log if r["kind"] == kind]
        if got:
            rows.append(
                {
                    "kind": kind,
                    "checks": len(got),
                    f"successes_{a}": sum(r["a"].success for r in got),
                    f"successes_{b}": sum(r["b"].success for r in got),
                    "differ": sum(not _same(r["a"], r["b"]) for r in got),
                    f"bodies_{a}": float(np.mean([r["bodies"][0] for r in got])),
                    f"bodies_{b}": float(np.mean([r["bodies"][1] for r in got])),
                    f"cpu_{a}_s": float(np.mean([r["a"].cpu for r in got])),
                    f"cpu_{b}_s": float(np.mean([r["b"].cpu for r in got])),
                }
            )
    return {
        "bench": what,
        "names": [a, b],
        "tables": tables,
        "seed": seed,
        "rows": rows,
        f"cpu_{a}_s": sum(r["a"].cpu for r in log),
        f"cpu_{b}_s": sum(r["b"].cpu for r in log),
        "differing": _differing(log, a, b),
    }


class _Timed:
    """A physics check whose results carry the CPU seconds of this thread it took (``cpu``):
    on a shared machine wall time mostly measures the neighbours."""

    def __init__(self, verifier):
        self.verifier = verifier

    @property
    def _sim(self):
        return self.verifier._sim

    def check(self, scene, group, grasp):
        t = time.thread_time()
        r = self.verifier.check(scene, group, grasp)
        r.cpu = time.thread_time() - t
        return r


def pair_text(doc: dict) -> str:
    from mog_drake.tables import format_table

    a, b = doc["names"]
    text = format_table(doc["rows"]) + (
        f"\nall checks: {doc[f'cpu_{a}_s']:.1f} s of CPU with {a}, {doc[f'cpu_{b}_s']:.1f} s with {b}; "
        f"{len(doc['differing'])} verdicts differ"
    )
    return text + "".join(
        f"\n  differs: {d['kind']} group {d['group']} grasp {[round(x, 5) for x in d['grasp']]}: "
        f"{a} {d[a]['success']} lifted {d[a]['lifted']}, {b} {d[b]['success']} lifted {d[b]['lifted']}"
        for d in doc["differing"]
    )


def hold_text(doc: dict) -> str:
    from mog_drake.tables import format_table

    text = format_table(doc["rows"]) + (
        f"\nall checks: {doc['wall_s']:.1f} s with the full hold, {doc['wall_settled_s']:.1f} s ending it "
        f"once settled ({doc['window_s']:g} s under {doc['settle_speed_m_s'] * 1e3:g} mm/s); "
        f"{len(doc['differing'])} verdicts differ"
    )
    return text + "".join(
        f"\n  differs: {d['kind']} group {d['group']} grasp {[round(x, 5) for x in d['grasp']]}: "
        f"full hold {d['full_hold']['success']} lifted {d['full_hold']['lifted']}, "
        f"settled {d['settled']['success']} lifted {d['settled']['lifted']}"
        for d in doc["differing"]
    )


def bench_checks(tables: int = 5, seed: int = 0, progress=None) -> dict:
    """The modelled clock's cost of a physics check against its CPU time
    (`mog_drake.planning.clock.WorkCost`). On each seeded isrr33 table (the scene seeds of
    ``eval picking --seed``), as the station settled it, Alg. 1's decisions clear the table
    without the robot (`station.clear_table`), and each check's CPU time on this thread, its
    simulated time and its object bodies are recorded. Returns the least-squares fit of
    ``check_s``, ``sim_s`` and ``body_sim_s`` (none negative) and, by bodies simulated, the
    mean CPU per check against the fit's and the scenario's cost. Run it alone: CPU time is
    stretched by anything else the machine runs."""
    from dataclasses import asdict

    from mog_drake.experiments.bench.station import clear_table
    from mog_drake.scenario import ClutteredScene, Scenario
    from mog_drake.station import scene_from_spec
    from mog_drake.systems.pick import make_planner

    sc = Scenario()
    planner = make_planner(sc)
    check, log = planner.verifier.check, []

    def timed(scene, group, grasp):
        c0 = time.thread_time()
        r = check(scene, group, grasp)
        if r.bodies:  # a simulation ran
            log.append((time.thread_time() - c0, r.sim_time, r.bodies))
        return r

    planner.verifier.check = timed
    for k in range(tables):
        scene = scene_from_spec(ClutteredScene(seed=seed * 1_000_000 + k))
        for _ in clear_table(scene, planner, sc.planner, seed * 1_000_000 + k):
            pass
        if progress:
            progress(k + 1, tables)
    if not log:
        raise MogError("no physics check ran: nothing to fit")
    cpu, sim, bodies = (np.array(c, dtype=float) for c in zip(*log))
    fit, now = fit_work_cost(cpu, sim, bodies), sc.latency.cost
    model = {
        "fit": np.array([fit.of(s, int(b)) for s, b in zip(sim, bodies)]),
        "scenario": np.array([now.of(s, int(b)) for s, b in zip(sim, bodies)]),
    }
    rows = []
    for lo, hi in ((0, 3), (3, 5), (5, 7), (7, 9), (9, 1000)):
        m = (bodies >= lo) & (bodies < hi)
        if m.any():
            rows.append(
                {
                    "bodies": f"{lo}-{hi - 1}" if hi < 1000 else f"{lo}+",
                    "checks": int(m.sum()),
                    "sim_s": round(float(sim[m].mean()), 2),
                    "cpu_s": round(float(cpu[m].mean()), 3),
                    "fit_s": round(float(model["fit"][m].mean()), 3),
                    "scenario_s": round(float(model["scenario"][m].mean()), 3),
                }
            )
    return {
        "rows": rows,
        "checks": len(log),
        "fit": {n: round(v, 4) for n, v in asdict(fit).items()},
        "scenario": asdict(now),
        "cpu_s": float(cpu.sum()),
        **{f"{k}_s": float(v.sum()) for k, v in model.items()},
        **{f"{k}_error": float(np.mean(np.abs(v - cpu) / cpu)) for k, v in model.items()},
    }


def fit_work_cost(cpu, sim, bodies):
    """The `WorkCost` whose cost of each simulation (``sim`` simulated seconds, ``bodies``
    object bodies) is nearest ``cpu`` in least squares, no term negative: a term that comes
    out negative is dropped (set to 0) and the rest fitted again."""
    from mog_drake.planning.clock import WorkCost

    cpu, sim, bodies = (np.asarray(v, dtype=float) for v in (cpu, sim, bodies))
    X = np.c_[np.ones_like(sim), sim, sim * bodies]
    names = ["check_s", "sim_s", "body_sim_s"]
    keep = list(range(3))
    while True:
        coef, *_ = np.linalg.lstsq(X[:, keep], cpu, rcond=None)
        if (coef >= 0).all() or len(keep) == 1:
            break
        keep.pop(int(np.argmin(coef)))
    fit = WorkCost(**{n: 0.0 for n in names})
    for j, c in zip(keep, coef):
        setattr(fit, names[j], max(0.0, float(c)))
    return fit


def checks_text(doc: dict) -> str:
    from mog_drake.tables import format_table

    fit = ", ".join(f"{k} {v:g}" for k, v in doc["fit"].items())
    now = ", ".join(f"{k} {v:g}" for k, v in doc["scenario"].items())
    return format_table(doc["rows"]) + (
        f"\n{doc['checks']} checks: {doc['cpu_s']:.1f} s of CPU; the fit ({fit}) models "
        f"{doc['fit_s']:.1f} s, each check off by {100 * doc['fit_error']:.0f} % on average; the "
        f"scenario's latency.cost ({now}) models {doc['scenario_s']:.1f} s "
        f"(off by {100 * doc['scenario_error']:.0f} %)"
    )
