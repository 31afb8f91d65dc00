"""The station and the application: perception on rendered tables, the station's step, replanning."""

from __future__ import annotations

import time

import numpy as np

from mog_drake.errors import MogError

PERCEPTION_REPEATS = 3


def bench_perception(
    tables: int = 5,
    seed: int = 0,
    toppled: int = 0,
    repeats: int = PERCEPTION_REPEATS,
    scenario=None,
    noise_levels=None,
    *,
    camera_height: float | None = None,
    calibrate: bool = False,
) -> list[dict]:
    """Perception accuracy on rendered cluttered isrr33 tables (seeds seed .. seed+tables-1):
        objects found, missed and extra, unrecognised blobs, median and worst position (mm) and yaw
        error (deg, modulo the shape's symmetry), the objects seen with a share of their pose
        error (``parted``: `station.seen.SeenPoses`), and wall time per image: ``time_s`` the median of
        ``repeats`` perceptions of the image (the steady state of a camera feeding frames; one run
        alone varies by tens of percent on a shared machine), ``first_s`` the first of them (cold
        caches), ``cpu_s`` the median CPU time (the process's: on a busy machine, what a quiet one
    would take). ``toppled`` bars per table are laid on their side before rendering (the pose a
        knocked-over bar takes). ``scenario``: a scenario file whose camera, perception and world
        (realism) are used, e.g. models/realistic.yaml; ``shift_mm`` is then the error every object
        shares (the median offset: the camera's calibration), ``fit_mm`` the median of the rest and
        ``fit_max_mm`` the worst. ``noise_levels``: depth noise levels (times the D435's RMS) to run
        each table at, in place of the scenario's (one row per level and table; the table is
        rendered once and each level's depth made from it as the station makes it:
        `realism.depth_artefacts`). ``camera_height`` (m): the camera's height above the table, in
        place of the scenario's. ``calibrate``: perception takes the camera's pose that a rendered
        board gives in each table's world (`hardware.calibration`), not the scenario's."""
    from dataclasses import replace

    from mog_drake.camera import camera_pose
    from mog_drake.scenario import ClutteredScene, load_scenario
    from mog_drake.sim.realism import depth_artefacts

    base = load_scenario(scenario)
    if camera_height is not None:
        if not 0.3 <= camera_height <= 3.0:
            raise MogError(f"--camera-height must be in [0.3, 3] m, got {camera_height}")
        base.camera.X_PB.translation = [*base.camera.X_PB.translation[:2], camera_height]
    levels = [base.realism.depth_noise] if noise_levels is None else list(noise_levels)
    rows = []
    for k in range(seed, seed + tables):
        sc = replace(base, scene=ClutteredScene(seed=k))
        # Rendered clean; each level's depth made from it below.
        quiet = replace(sc.realism, depth_noise=0.0, depth_holes=0.0, flying_pixels=0.0)
        rgb, clean, truth, K = _render_table(replace(sc, realism=quiet), k, toppled)
        world = sc.realism.draw(k, len(truth.scene))
        perceiver = sc.perceiver()
        X_WC = camera_pose(sc.camera)
        if calibrate:
            from mog_drake.hardware.calibration import board_in_table, solve
            from mog_drake.station.board import board_frame

            X_WC = solve(*board_frame(sc)[:3], board_in_table(0.0, 0.0, 0.0)).X_TC
        for level in levels:
            depth = depth_artefacts(
                clean,
                rgb,
                world.depth_rng(0.0),
                noise=level,
                holes=world.depth_holes,
                flying=world.flying_pixels,
                fx=K[0],
            )
            times, cpus = [], []
            for _ in range(max(repeats, 1)):
                t, c = time.perf_counter(), time.process_time()
                seen = perceiver.perceive(rgb, depth, X_WC, K)
                times.append(time.perf_counter() - t)
                cpus.append(time.process_time() - c)
            row = {
                "noise": level,
                "table_seed": k,
                "objects": len(truth.scene),
                "toppled": truth.laid,
                "parted": truth.parted,
            }
            rows.append(
                {
                    **row,
                    **_scores(seen, truth.scene),
                    "time_s": float(np.median(times)),
                    "cpu_s": float(np.median(cpus)),
                    "first_s": times[0],
                }
            )
    return rows


class _Rendered:
    def __init__(self, scene, laid, parted):
        # parted: the objects seen with a share of their pose error (`SeenPoses`)
        self.scene, self.laid, self.parted = scene, laid, parted


def _render_table(sc, k: int, toppled: int):
    """(rgb, depth, truth, intrinsics) of table ``k`` as the station of ``sc`` renders it,
    ``toppled`` of its bars laid on their side."""
    from mog_drake.scenes import Scene, SceneObject, cluttered_scene, default_library
    from mog_drake.station import MakeStation, render_still

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
    d, h = MakeStation(sc, scene)
    ctx = d.CreateDefaultContext()
    seen = h.seen_poses(0.0)
    if seen:  # as the pick loop shows them: two objects never one inside the other
        seen.update(ctx)
    rgb, depth = render_still(sc, d, ctx)
    parted = sum(item.share < 1.0 for item in seen.items) if seen else 0
    return np.array(rgb), np.array(depth), _Rendered(h.scene, laid, parted), h.camera_intrinsics


def _scores(seen, truth) -> dict:
    """The perceived scene ``seen`` against ``truth``: counts and errors (mm, deg)."""
    from mog_drake.perception import pose_errors

    errs = pose_errors(seen, truth)
    found = [e for e in errs if e["object"] is not None and e["position"] is not None]
    pos = 1e3 * np.array([e["position"] for e in found])
    yaw = np.degrees([e["yaw"] for e in found])
    offsets = np.array([e["offset"] for e in found]).reshape(-1, 2)
    shift = np.median(offsets, axis=0) if len(found) else np.full(2, np.nan)
    fit = 1e3 * np.linalg.norm(offsets - shift, axis=1)
    nan = float("nan")
    return {
        "found": len(found),
        "missed": sum(e["object"] is not None and e["position"] is None for e in errs),
        "extra": sum(bool(e.get("extra")) for e in errs),
        "unrecognised": seen.meta["unrecognised_blobs"],
        "pos_median_mm": float(np.median(pos)) if len(pos) else nan,
        "pos_max_mm": float(pos.max()) if len(pos) else nan,
        "shift_mm": 1e3 * float(np.linalg.norm(shift)),
        "fit_mm": float(np.median(fit)) if len(found) else nan,
        "fit_max_mm": float(fit.max()) if len(found) else nan,
        "yaw_median_deg": float(np.median(yaw)) if len(yaw) else nan,
        "yaw_max_deg": float(yaw.max()) if len(yaw) else nan,
    }


def bench_station(seed: int = 0, sim_seconds: float = 1.0) -> list[dict]:
    """CPU seconds per simulated second of the simulated station (arm still at its observe
    pose, jaws open) with a whole isrr33 table in four states: every object on the table,
    awake; the same asleep (`station.speed`: each at rest, out of the gripper's reach); every
    object piled in the bin; and the pile retired (`BinRetirement`)."""
    from pydrake.math import RigidTransform
    from pydrake.multibody.math import SpatialVelocity

    from mog_drake.scenario import ClutteredScene, Scenario
    from mog_drake.station import still_station
    from mog_drake.station.speed import BinRetirement
    from mog_drake.systems.pick import SLEEP_PERIOD

    sc = Scenario(scene=ClutteredScene(seed=seed))
    sim, h, pc = still_station(sc)
    ctx = sim.get_mutable_context()
    sim.Initialize()
    sim.AdvanceTo(0.3)
    retire = sleep = None

    def advance(seconds: float) -> None:
        end = ctx.get_time() + seconds
        while ctx.get_time() < end - 1e-9:
            sim.AdvanceTo(min(ctx.get_time() + (SLEEP_PERIOD if sleep else 0.25), end))
            if retire is not None:
                retire.update(pc)
            if sleep is not None:
                sleep.update(ctx)

    def cost(**extra) -> dict:
        t0 = time.process_time()
        advance(sim_seconds)
        return {
            **extra,
            "objects": len(h.bodies),
            "asleep": len(sleep.asleep) if sleep else 0,
            "cpu_s_per_sim_s": (time.process_time() - t0) / sim_seconds,
        }

    rows = [cost(state="on the table")]
    sleep = h.sleep(SLEEP_PERIOD)
    advance(0.5)  # at rest long enough: asleep
    rows.append(cost(state="on the table, asleep"))
    sleep.wake(ctx)
    sleep = None
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


# The time a decision has beside the arm (s): the next image is taken as the arm leaves the
# table, and the arm going on from over the bin needs the next grasp about 1 s later (the
# median in v22_shipped's push-mog runs, models/realistic.yaml's cycle).
FREE_PLANNING_S = 1.0


def clear_table(scene, planner, spec, seed: int, remember: bool = True):
    """Clears ``scene`` by decisions without the robot: plan (`next_pick`, its random draws
    seeded with ``seed``; ``remember``: failed groups remembered across decisions), remove the
    objects the physics check lifted, plan again, until the table is empty, a decision finds
    no grasp, or three decisions per object. In push-mog a push leaves the table where its
    simulation did (at most ``spec.pushes.max_per_table``), and its grasp follows. Yields
    (decision, its CPU time on this thread, the table left after it)."""
    from mog_drake.planning.picking import next_pick
    from mog_drake.scenes import Scene

    rng, failures = np.random.default_rng(seed), () if remember else None
    pushes = spec.pushes.max_per_table if spec.mode == "push-mog" else 0
    for _ in range(3 * len(scene)):
        if not len(scene):
            return
        c0 = time.thread_time()
        d = next_pick(scene, planner, spec, rng=rng, failures=failures, pushes_left=pushes)
        cpu = time.thread_time() - c0
        failures = d.failures if remember else None
        if d.status == "push":
            pushes -= 1
            scene = d.after
        if d.status in ("grasp", "push") and d.grasp is not None:
            gone = set(d.expected) or set(d.group)
            scene = Scene(
                [o for i, o in enumerate(scene.objects) if i not in gone], scene.library, scene.table
            )
        yield d, cpu, scene
        if d.status not in ("grasp", "push"):
            return


def bench_replanning(
    tables: int = 1, seed: int = 0, progress=None, scenario: str | None = None, mode: str | None = None
) -> list[dict]:
    """Planning time of one table's decisions, replayed without the robot (`clear_table`) on
    each seeded isrr33 table (the scene seeds of ``eval picking --seed``), with ``scenario``'s
    planner (the default one when None) in ``mode`` (the scenario's when None), and again with
    groups of three or more checked as often as any (``planner.grasp.max_physics_large``
    off). Per table and setting: decisions, objects per decision, physics checks, planning
    CPU (this thread's), the first decision's, and the part of each decision's CPU past
    FREE_PLANNING_S summed (what the arm would wait with no lookahead)."""
    from dataclasses import replace

    from mog_drake.scenario import ClutteredScene, Scenario, load_scenario
    from mog_drake.station import scene_from_spec
    from mog_drake.systems.pick import make_planner

    sc = Scenario() if scenario is None else load_scenario(scenario)
    spec = replace(sc.planner, mode=mode or sc.planner.mode)
    spec.check()
    grasp = spec.grasp
    if (
        grasp.max_physics_large is None
        or grasp.max_physics is None
        or grasp.max_physics_large >= grasp.max_physics
    ):
        raise MogError(
            f"bench replanning compares planner.grasp.max_physics_large with none: {scenario or 'the default scenario'} "
            "sets none below planner.grasp.max_physics"
        )
    settings = {
        f"{grasp.max_physics} checks": replace(grasp, max_physics_large=None),
        f"{grasp.max_physics_large} checks": grasp,
    }
    rows, done = [], 0
    for k in range(tables):
        table_seed = seed * 1_000_000 + k
        for setting, config in settings.items():
            planner = make_planner(sc)  # a new planner (and its plants) per table and setting
            planner.config = config
            scene = scene_from_spec(ClutteredScene(seed=table_seed))
            n0, decisions, checks, cpu, past, n_left, first = len(scene), 0, 0, 0.0, 0.0, len(scene), None
            for d, c, left in clear_table(scene, planner, spec, table_seed):
                n_left = len(left)
                cpu += c
                first = c if first is None else first
                past += max(0.0, c - FREE_PLANNING_S)
                decisions += 1
                checks += d.physics_checks
            rows.append(
                {
                    "table_seed": table_seed,
                    "large groups": setting,
                    "decisions": decisions,
                    "objects_per_decision": round((n0 - n_left) / max(decisions, 1), 2),
                    "objects_left": n_left,
                    "physics_checks": checks,
                    "cpu_s": round(cpu, 1),
                    "first_s": round(first or 0.0, 1),
                    f"cpu_past_{FREE_PLANNING_S:g}s": round(past, 1),
                }
            )
            done += 1
            if progress:
                progress(done, 2 * tables)
    return rows


# Restless after settling: an object at rest on the table turns slower than this (rad/s) and
# moves slower than this (m/s); a toppled bar buzzing on too few contact points did 1-12 rad/s.
REST_TURN = 0.05
REST_SPEED = 0.005
# Where `bench rest` lays its copies: the table in front of the arm, clear of the bin (m).
REST_REGION = (-0.2, 0.4, -0.4, 0.2)


def bench_rest(
    spots: int = 20, seed: int = 0, settle: float = 1.0, watch: float = 3.0, progress=None
) -> dict:
    """Objects left alone on the simulated station's table (arm still at its observe pose),
    with hydroelastic contact surfaces as polygons and as triangles
    (``ContactConfig.plant.contact_surface_representation``). For every shape of the default
    library and every resting form of a bar (``NAME:on_side``, ``NAME:on_end``): ``spots``
    copies at seeded random, well-separated spots and yaws of REST_REGION, in one
    station, settled ``settle`` s, then watched ``watch`` s. Per shape and representation:
    the copies restless (turning faster than REST_TURN or moving faster than REST_SPEED at
    any 0.05 s sample), the worst turn rate and speed, and CPU seconds per simulated second;
    a solver failure is reported as such."""
    from mog_drake.scenario import Scenario
    from mog_drake.scenes import Scene, SceneObject, default_library
    from mog_drake.station import fastest_motion, still_station

    x0, x1, y0, y1 = REST_REGION
    cols, rows_ = int((x1 - x0 - 0.06) // 0.1), int((y1 - y0 - 0.06) // 0.1)
    if not 1 <= spots <= cols * rows_:
        raise MogError(f"rest bench: copies per shape (--scenes) must be 1..{cols * rows_}, got {spots}")
    library = default_library()
    names = sorted(library.shapes) + sorted(library.resting_variants())
    rows, done = [], 0
    for n, name in enumerate(names):
        rng = np.random.default_rng([seed, n])
        # A jittered grid: copies 8 cm or more apart, so none touches another.
        objs = []
        for k in range(spots):
            gx, gy = k % cols, k // cols
            x = x0 + 0.05 + 0.1 * gx + rng.uniform(-0.01, 0.01)
            y = y0 + 0.05 + 0.1 * gy + rng.uniform(-0.01, 0.01)
            objs.append(SceneObject(name, float(x), float(y), float(rng.uniform(-np.pi, np.pi))))
        scene = Scene(objs, library, table=(x0, x1, y0, y1))
        for rep in ("polygon", "triangle"):
            sc = Scenario()
            sc.contact.plant.contact_surface_representation = rep
            sim, h, pc = still_station(sc, scene)
            bodies = list(h.bodies.values())
            worst = np.zeros((len(bodies), 2))
            failed = ""
            try:
                sim.AdvanceTo(settle)
                c0 = time.process_time()
                worst = fastest_motion(sim, h.plant, pc, bodies, settle + watch)
                cpu = (time.process_time() - c0) / watch
            except RuntimeError as e:
                failed, cpu = str(e).split(".")[0][:60], float("nan")
            turn, speed = worst[:, 0], worst[:, 1]
            rows.append(
                {
                    "shape": name,
                    "surface": rep,
                    "copies": len(bodies),
                    "restless": "-" if failed else int(np.sum((turn > REST_TURN) | (speed > REST_SPEED))),
                    "max_turn_rad_s": float(turn.max()),
                    "max_speed_mm_s": float(1e3 * speed.max()),
                    "cpu_s_per_sim_s": cpu,
                    "failed": failed,
                }
            )
        done += 1
        if progress:
            progress(done, len(names))
    return {"spots": spots, "seed": seed, "settle_s": settle, "watch_s": watch, "rows": rows}


def rest_text(doc: dict) -> str:
    from mog_drake.tables import format_table

    rows = doc["rows"]
    text = format_table([{k: v for k, v in r.items() if k != "failed" or v} for r in rows])
    for rep in ("polygon", "triangle"):
        got = [r for r in rows if r["surface"] == rep]
        restless = sum(r["restless"] for r in got if r["restless"] != "-")
        failed = sum(bool(r["failed"]) for r in got)
        cpu = np.nanmean([r["cpu_s_per_sim_s"] for r in got])
        text += (
            f"\n{rep}: {restless} of {sum(r['copies'] for r in got)} objects restless after "
            f"{doc['settle_s']:g} s, {failed} stations failed; mean {cpu:.2f} CPU s per simulated s"
        )
    return text
