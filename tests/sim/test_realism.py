"""The realistic cell (`mog_drake.sim.realism`) and robust grasps (`mog_drake.planning.robust`)."""

from dataclasses import replace

import numpy as np
import pytest
import shapely
from conftest import make_scene
from pydrake.geometry import Role
from pydrake.math import RollPitchYaw

from mog_drake.errors import MogError
from mog_drake.planning.config import RobustConfig
from mog_drake.planning.protocol import GraspResult
from mog_drake.planning.robust import RobustVerifier
from mog_drake.scenario import ClutteredScene, Scenario, load_scenario
from mog_drake.sim.realism import (
    D435_BASELINE,
    FLY_JUMP,
    RealismConfig,
    d435_rms,
    depth_artefacts,
    seen_in_body,
)
from mog_drake.sim.verifier import DrakeVerifier

REAL = RealismConfig(
    camera_offset=0.0015,
    camera_tilt_deg=0.1,
    depth_noise=1.0,
    mass_spread=0.2,
    friction_spread=0.3,
    finger_friction_spread=0.3,
    table_friction_spread=0.3,
    tcp_offset=0.001,
    depth_holes=0.01,
    flying_pixels=0.3,
    pose_error=0.002,
    yaw_error_deg=2.0,
    size_error=0.0005,
    grip_force_spread=0.2,
)


def _same(a, b) -> bool:
    return all(np.array_equal(getattr(a, k), getattr(b, k)) for k in vars(a))


def test_the_realistic_cell_is_seeded_per_table_and_off_by_default():
    assert _same(REAL.draw(3, 33), REAL.draw(3, 33))  # the same world, every mode on a table
    assert not _same(REAL.draw(3, 33), REAL.draw(4, 33))  # another table, another world
    other = RealismConfig(**{**vars(REAL), "seed": 1})
    assert not _same(REAL.draw(3, 33), other.draw(3, 33))
    w = REAL.draw(0, 33)
    assert np.all(np.abs(w.mass - 1) <= 0.2) and np.all(np.abs(w.friction - 1) <= 0.3)
    assert w.tcp_offset[2] == 0 and 0 < np.linalg.norm(w.tcp_offset) < 0.01
    ideal = RealismConfig().draw(3, 33)
    assert not RealismConfig().enabled and REAL.enabled
    assert np.all(ideal.mass == 1) and np.all(ideal.friction == 1) and not ideal.camera_offset.any()
    # The D435's RMS depth error at the camera's 0.8 m (Intel's tuning guide): about 2.3 mm.
    assert d435_rms(0.8) == pytest.approx(0.0023, abs=1e-4)


def _block_on_table(z_table=0.8, z_top=0.77, fx=600.0):
    """A depth image of a 40 x 40 pixel block on a table, and its colour image (mid-grey)."""
    z = np.full((120, 160), z_table, np.float32)
    z[40:80, 60:100] = z_top
    return z, np.full((120, 160, 3), 128, np.uint8), fx


def test_depth_artefacts_are_seeded_and_off_by_default():
    z, rgb, fx = _block_on_table()
    assert np.array_equal(depth_artefacts(z, rgb, np.random.default_rng(0), fx=fx), z)  # nothing asked
    art = dict(noise=2.0, holes=0.02, flying=0.5, fx=fx)
    a = depth_artefacts(z, rgb, np.random.default_rng(1), **art)
    b = depth_artefacts(z, rgb, np.random.default_rng(1), **art)
    c = depth_artefacts(z, rgb, np.random.default_rng(2), **art)
    assert np.array_equal(a, b, equal_nan=True) and not np.array_equal(a, c, equal_nan=True)
    # The drawn world carries them, zero by default.
    w = RealismConfig(depth_holes=0.01, flying_pixels=0.3).draw(0, 3)
    assert w.depth_holes == 0.01 and w.flying_pixels == 0.3 and w.depth_artefacts
    assert not RealismConfig().draw(0, 3).depth_artefacts


def test_holes_fall_where_the_right_imager_cannot_see_and_flying_pixels_between_two_depths():
    z, rgb, fx = _block_on_table()
    # Holes: the table just left of the block is hidden from the right imager over the
    # disparity step f B (1/z_top - 1/z_table) (1.46 px here); the rest at the share asked.
    holes = depth_artefacts(z, rgb, np.random.default_rng(3), holes=1e-6, fx=fx)
    step = fx * D435_BASELINE * (1 / 0.77 - 1 / 0.8)
    hidden = np.isnan(holes)
    assert hidden[40:80, 60 - int(step) : 60].all() and not hidden[40:80, 60 - int(np.ceil(step)) - 1].any()
    assert not hidden[40:80, 100:].any() and not hidden[:, :55][np.r_[0:40, 80:120]].any()
    white, dark = np.full_like(rgb, 255), np.full_like(rgb, 40)
    many = depth_artefacts(z, white, np.random.default_rng(3), holes=0.05, fx=fx)
    assert 0.04 < np.isnan(many[:30, :50]).mean() < 0.06  # bright flat table: the share itself
    darker = depth_artefacts(z, dark, np.random.default_rng(3), holes=0.05, fx=fx)
    assert 3 * 0.05 < np.isnan(darker[:30, :50]).mean() < 4 * 0.05  # 1 + HOLE_DARK (1 - 40 / 255)
    # Flying pixels: only on either side of the block's edge, between its depth and the table's.
    fly = depth_artefacts(z, rgb, np.random.default_rng(4), flying=1.0, fx=fx)
    moved = fly != z
    edge = np.zeros(z.shape, bool)
    edge[39:81, 59:101] = True
    edge[41:79, 61:99] = False
    assert moved.any() and not (moved & ~edge).any()
    assert np.all((fly[moved] >= 0.77) & (fly[moved] <= 0.8)) and FLY_JUMP < 0.03


def test_the_pose_error_of_an_object_lying_any_way_up_stays_in_the_table_plane():
    """`seen_in_body`: upright, the error in the body's own frame (as registered); on its side
    or on its end, the same shift and turn in the table's plane, nothing vertical."""
    from pydrake.math import RotationMatrix

    off = (0.003, -0.004, 0.05)
    Rz = RotationMatrix.MakeZRotation
    R_BG, p_BG = seen_in_body(Rz(0.7).matrix(), off)
    assert np.allclose(R_BG, Rz(0.05).matrix()) and np.allclose(p_BG, [0.003, -0.004, 0.0])
    for R_WB in (
        Rz(0.7) @ RotationMatrix.MakeXRotation(np.pi / 2),  # on its side
        Rz(0.7) @ RotationMatrix.MakeXRotation(-np.pi / 2),
        Rz(-1.2) @ RotationMatrix.MakeYRotation(np.pi / 2),  # on its end
    ):
        R = R_WB.matrix()
        R_BG, p_BG = seen_in_body(R, off)
        shift, turn = R @ p_BG, R @ R_BG @ R.T  # in the world
        assert shift[2] == pytest.approx(0.0, abs=1e-12)
        assert np.linalg.norm(shift) == pytest.approx(0.005)
        assert np.allclose(turn, Rz(0.05).matrix())


def test_a_bar_knocked_onto_its_side_is_seen_where_its_pose_error_puts_it_in_the_table_plane():
    """A thin bar (7 mm tall on its side) with a pose error of 5.6 mm along its own y axis,
    knocked over so that the error points down, then up. Left in the body frame, the error
    sinks the bar's image into the table, its top 1.4 mm up (perception finds nothing), or
    lifts it by 5.6 mm; `SeenPoses` re-places it in the table's plane and perception finds the
    bar on its side, within the error of its true footprint, either way."""
    from pydrake.math import RigidTransform, RotationMatrix

    from mog_drake.camera import camera_pose
    from mog_drake.sim.models import prism_points
    from mog_drake.station import MakeStation, render_still

    sc = Scenario(realism=RealismConfig(pose_error=0.007))
    d, h = MakeStation(sc, make_scene([("thin_bar", 0.0, 0.0, 0.3)]))
    (_, dy, _), err = h.seen[0], np.linalg.norm(h.seen[0][:2])
    assert abs(dy) > 0.0045  # the draw this test stands on: more than a 7 mm bar's margin
    ctx = d.CreateDefaultContext()
    pc = h.plant.GetMyContextFromRoot(ctx)
    body, seen = h.bodies[0], h.seen_poses(0.0)
    perceiver = sc.perceiver()

    def bars_near(centre):
        rgb, depth = render_still(sc, d, ctx)
        found = perceiver.perceive(rgb, depth, camera_pose(sc.camera), h.camera_intrinsics).objects
        return [
            o
            for o in found
            if o.shape == "thin_bar:on_side" and np.hypot(o.x - centre[0], o.y - centre[1]) < 0.02
        ]

    down = -np.sign(dy) * np.pi / 2  # turns the body's y axis, and dy with it, down
    for roll in (down, -down):
        X = RigidTransform(
            RotationMatrix.MakeZRotation(0.3) @ RotationMatrix.MakeXRotation(roll), [0, 0, 0.0035]
        )
        h.plant.SetFreeBodyPose(pc, body, X)
        footprint = X.multiply(prism_points(h.scene.shape(0)))[:2].mean(axis=1)
        if roll == down:
            assert not bars_near(footprint)
        seen.update(ctx)
        # (Re-placing a geometry does not invalidate a render already cached in this context;
        # in a simulation every step does.)
        h.plant.SetFreeBodyPose(pc, body, X)
        (bar,) = bars_near(footprint)
        assert np.hypot(bar.x - footprint[0], bar.y - footprint[1]) < err + 0.002
    assert seen.moves == 2


def test_two_bars_side_by_side_are_never_seen_one_inside_the_other():
    """Two upright thin bars 9 mm apart (a 2 mm gap), their pose errors 4 mm across them,
    towards each other. Seen with their whole errors, the two images overlap by 6 mm and the
    depth image shows one bar: perception finds one. `SeenPoses` sees both with the share of
    their errors that parts them, perception finds both, and a bar far off keeps its whole
    error."""
    from mog_drake.camera import camera_pose
    from mog_drake.sim.models import prism_points
    from mog_drake.station import MakeStation, render_still
    from mog_drake.station.seen import SeenPoses

    th = 0.4
    across = np.array([-np.sin(th), np.cos(th)])  # each bar's own y axis
    a, b = np.array([0.0, 0.02]), np.array([0.0, 0.02]) + 0.009 * across
    mid = (a + b) / 2
    sc = Scenario()
    scene = make_scene([("thin_bar", *a, th), ("thin_bar", *b, th), ("thin_bar", 0.1, -0.1, 1.0)])
    offsets = {
        0: np.array([0.0, 0.004, 0.0]),
        1: np.array([0.0, -0.004, 0.0]),
        2: np.array([0.0, 0.004, 0.0]),
    }
    perceiver = sc.perceiver()
    found = {}
    for rule in ("whole errors", "parted"):
        d, h = MakeStation(sc, scene)
        ctx = d.CreateDefaultContext()
        points = {i: prism_points(scene.shape(i)) for i in offsets}
        seen = SeenPoses(h.plant, h.scene_graph, h.bodies, offsets, 0.0, points)
        if rule == "whole errors":
            seen.OVERLAP_M2 = np.inf
        seen.update(ctx)
        rgb, depth = render_still(sc, d, ctx)
        objects = perceiver.perceive(rgb, depth, camera_pose(sc.camera), h.camera_intrinsics).objects
        found[rule] = [o for o in objects if np.hypot(o.x - mid[0], o.y - mid[1]) < 0.02]
        shares = [item.share for item in seen.items]
    assert len(found["whole errors"]) == 1
    assert len(found["parted"]) == 2
    assert shares[0] == shares[1] < 1.0 and shares[2] == 1.0


def test_realism_settings_are_checked_at_load(tmp_path):
    f = tmp_path / "bad.yaml"
    f.write_text("realism:\n  mass_spread: 1.5\n")
    with pytest.raises(MogError, match=r"realism.mass_spread must be in \[0, 0.9\], got 1.5"):
        load_scenario(str(f))
    f.write_text("realism:\n  depth_noise: 1.0\nhardware:\n  enabled: true\n  robot_ip: 10.0.0.2\n")
    with pytest.raises(MogError, match="realism applies to the simulated cell"):
        load_scenario(str(f))
    f.write_text("planner:\n  robust:\n    samples: 4\n    required: 5\n")
    with pytest.raises(MogError, match="planner.robust"):
        load_scenario(str(f))
    assert load_scenario("models/realistic.yaml").realism.enabled


def test_the_station_builds_the_drawn_world_and_the_planner_sees_only_perception():
    from mog_drake.station import MakeStation, render_still
    from mog_drake.systems.pick import MakePickDiagram, make_planner
    from mog_drake.systems.planner import PlannerSystem

    sc = Scenario(scene=ClutteredScene(seed=2, n_objects=6))
    sc.realism = REAL
    d, h = MakeStation(sc)
    w = REAL.draw(2, 6)
    ctx = d.CreateDefaultContext()
    pc = h.plant.GetMyContextFromRoot(ctx)
    inspector = h.scene_graph.model_inspector()
    for i, body in h.bodies.items():
        shape = h.scene.shape(i)
        grown = shapely.Polygon(shape.vertices).buffer(w.size_offset[i], join_style="mitre").area
        assert body.get_mass(pc) == pytest.approx(shape.density * grown * shape.height * w.mass[i], rel=1e-6)
        # The camera sees it at its own pose error; collision and Meshcat where it is.
        frame = h.plant.GetBodyFrameIdOrThrow(body.index())
        seen = inspector.GetGeometries(frame, Role.kPerception)
        shown = inspector.GetGeometries(frame, Role.kIllustration)
        X = inspector.GetPoseInFrame(seen[0])
        assert len(seen) == len(shown) == 1 and seen != shown
        assert np.allclose([*X.translation()[:2], RollPitchYaw(X.rotation()).yaw_angle()], w.pose_offset[i])
        assert inspector.GetPoseInFrame(shown[0]).IsExactlyIdentity()
    finger = h.plant.GetJointActuatorByName("left_finger_motor", h.robot)
    assert finger.effort_limit() == pytest.approx(sc.gripper.force_limit * w.grip_force)
    # Depth noise: the same image twice is the same; at another time it is not.
    d1 = render_still(sc, d, ctx)[1].copy()
    d2 = render_still(sc, d, ctx)[1].copy()
    assert np.array_equal(d1, d2, equal_nan=True)
    ctx.SetTime(1.0)
    d3 = render_still(sc, d, ctx)[1].copy()
    diff = (d3 - d1)[np.isfinite(d1) & np.isfinite(d3)]
    assert 0.002 < np.std(diff) / np.sqrt(2) < 0.0035
    # Structure: the planner's one input is perception's scene; its physics check is the
    # scenario's nominal model, not the station's world.
    parts = MakePickDiagram(sc)
    diagram = parts.diagram
    planner = parts.planner
    assert isinstance(planner, PlannerSystem) and planner.num_input_ports() == 1
    ((src, port),) = [v for (dst, _), v in diagram.connection_map().items() if dst is planner]
    assert src is parts.perception and src.get_output_port(port).get_name() == "scene"
    check = make_planner(sc).verifier
    assert check.objects is None and check.config == sc.verifier and check.physics == sc.gripper


def _off_centre_grasp():
    """A lone cube gripped with its edge 1 mm inside the right jaw's open inner face."""
    scene = make_scene([("small_yellow_cube", 0.0, 0.0, 0.0)], group=[0])
    half_stroke = 0.0375  # the open jaws' inner faces, from the grasp centre
    return scene, np.array([0.0125 + 0.001 - half_stroke, 0.0, 0.0])


def test_a_grasp_that_fails_2_mm_off_is_rejected_by_the_robust_check_and_passed_by_the_plain_one():
    sc = Scenario()
    plain = DrakeVerifier(sc.verifier, physics=sc.gripper)
    scene, grasp = _off_centre_grasp()
    assert plain.check(scene, [0], grasp).success  # at the perceived pose it lifts
    shifted = make_scene([("small_yellow_cube", 0.002, 0.0, 0.0)], group=[0])
    assert not plain.check(shifted, [0], grasp).success  # 2 mm off, the open jaw lands on it
    cfg = RobustConfig(samples=6, shift_sigma=0.003)
    robust = RobustVerifier(plain, [plain.variant(_scales(cfg, k)) for k in range(6)], cfg)
    r = robust.check(scene, [0], grasp)
    assert not r.success and "not robust" in r.error
    assert robust.check(scene, [0], grasp).success is False  # the same verdict asked again
    centred = robust.check(scene, [0], np.array([0.0, 0.0, 0.0]))
    assert centred.success and centred.lifted == [0]
    # The first perturbed world is the hardest to hold in: slippery, heavy objects and pads.
    worst = _scales(cfg, 0)
    assert np.all(worst["friction"] == 0.7) and np.all(worst["mass"] == 1.2) and worst["finger"] == 0.7


def _scales(cfg, k):
    from mog_drake.planning.robust import perturbation_scales

    return perturbation_scales(cfg, k, 10)


def test_perception_on_the_realistic_cell_reports_the_calibration_as_one_shared_shift():
    """The realistic cell's table 0 (models/realistic.yaml: calibration error, depth noise):
    with the table's plane fitted, every object is found; their error is nearly all one
    shift shared by every object, a few millimetres, each fit within a fraction of one."""
    from mog_drake.experiments.bench.station import bench_perception

    (real,) = bench_perception(1, 0, repeats=1, scenario="models/realistic.yaml")
    assert real["found"] == 33 and real["extra"] == real["unrecognised"] == 0
    assert 1.0 < real["shift_mm"] < 6.0 and real["fit_mm"] < 0.6
    (ideal,) = bench_perception(1, 0, repeats=1)
    assert ideal["shift_mm"] < 0.3 and ideal["pos_max_mm"] < 1.0


@pytest.mark.parametrize("height,levels", [(0.8, (2.0, 4.0)), (1.2, (1.0,))])
def test_perception_invents_nothing_on_noisy_depth_with_holes_and_flying_pixels(tmp_path, height, levels):
    """The realistic cell's table 0 with holes and flying pixels, its depth noise at twice and
    four times the D435's, and the camera at 1.2 m (the noise grows with the square of the
    distance, and each pixel covers 1.9 mm): colour tells the table from the objects, so noise
    never makes an object; at 2x every object is found, each fit within 3 mm."""
    from mog_drake.experiments.bench.station import bench_perception

    f = tmp_path / "artefacts.yaml"
    f.write_text(
        "realism: {camera_offset: 0.0015, camera_tilt_deg: 0.1, depth_holes: 0.01, flying_pixels: 0.3}\n"
        "perception: {fit_table: true}\n"
    )
    rows = bench_perception(1, 0, repeats=1, scenario=str(f), noise_levels=levels, camera_height=height)
    assert all(r["extra"] == 0 for r in rows)
    first = rows[0]
    assert first["found"] == 33 and first["missed"] == first["unrecognised"] == 0
    assert first["fit_max_mm"] < 3.0


def test_the_last_resort_takes_a_nominal_grasp_when_no_robust_one_is_left():
    """A lone bar every perturbed world drops: no robust grasp, so Alg. 1's decision finds
    none; its last resort plans with the nominal check and takes the grasp, rather than
    leaving the bar to a person. Without the last resort the run would end on no_grasp."""
    from mog_drake.planning.config import LoopConfig, PlannerSpec
    from mog_drake.planning.picking import next_pick
    from mog_drake.planning.planner import GraspConfig, GraspPlanner
    from mog_drake.planning.protocol import GraspResult

    class Lifts:
        def check(self, scene, group, grasp):
            return GraspResult(True, list(group))

    class Drops:
        def check(self, scene, group, grasp):
            return GraspResult(False)

    scene = make_scene([("thick_bar", 0.0, 0.0, 0.3)], group=[0])
    robust = RobustVerifier(Lifts(), [Drops(), Drops()], RobustConfig(samples=2))
    planner = GraspPlanner(robust, GraspConfig("gp", max_physics=2))
    d = next_pick(scene, planner, PlannerSpec())
    assert d.status == "grasp" and d.last_resort and d.group == (0,)
    plain = next_pick(scene, planner, PlannerSpec(loop=LoopConfig(last_resort=False)))
    assert plain.status == "no_grasp"


def test_a_partial_lift_at_the_perceived_poses_stays_a_partial_lift_under_the_robust_check():
    """The nominal check runs first, and a grasp it fails is not checked further: a partial
    lift (2 of 3 lifted, no error) comes back as it is, so that the grasp planner keeps it as
    its best lift and mog's loop may take it. Run the other way round (the perturbed world
    first), every failed check carried "not robust" as its error, no partial lift was kept,
    and mog planned every group to the end (v21_robust: 2.1x the candidates per table)."""
    from mog_drake.planning.planner import GraspConfig, GraspPlanner
    from mog_drake.planning.protocol import GraspResult

    class Fake:
        def __init__(self, success, lifted):
            self.success, self.lifted, self.calls = success, lifted, 0

        def check(self, scene, group, grasp):
            self.calls += 1
            return GraspResult(self.success, list(self.lifted))

    scene = make_scene(
        [("thick_bar", 0.0, 0.0, 0.0), ("thick_bar", 0.0, 0.02, 0.0), ("thick_bar", 0.0, 0.04, 0.0)]
    )
    across = np.array([0.0, 0.02, np.pi / 2])  # the open jaws 11.5 mm clear of the bars, moved or not
    base, variant = Fake(False, [0, 1]), Fake(False, [0])  # the hardest world lifts one
    robust = RobustVerifier(base, [variant], RobustConfig(samples=1))
    r = robust.check(scene, [0, 1, 2], across)
    assert not r.success and r.lifted == [0, 1] and r.error == ""
    assert (base.calls, variant.calls) == (1, 0)
    plan = GraspPlanner(robust, GraspConfig(max_physics=1)).plan(scene, [0, 1, 2])
    assert plan.best_lift is not None and plan.best_lift[1] == [0, 1]
    # A grasp the nominal check passes must lift the group in the perturbed world too.
    base, variant = Fake(True, [0, 1, 2]), Fake(False, [0])
    r = RobustVerifier(base, [variant], RobustConfig(samples=1)).check(scene, [0, 1, 2], across)
    assert not r.success and r.error.startswith("not robust") and (base.calls, variant.calls) == (1, 1)


class _Lifts:
    """A check that lifts every group, counting its calls."""

    def __init__(self):
        self.calls = 0

    def check(self, scene, group, grasp):
        self.calls += 1
        return GraspResult(True, list(group))


def test_a_grasp_whose_open_jaws_land_on_an_object_once_moved_is_refused_without_physics():
    """The screen: the sample's moved poses put a bar under a jaw, so the perturbed check
    would fail at its start. Neither check is run, and the nominal check's lift is not kept
    (the grasp is refused whole, as it would be after both checks); with ``required`` below
    the samples, one screened world is a failed sample, not a refusal."""
    scene = make_scene([("thick_bar", 0.0, 0.0, 0.0), ("thick_bar", 0.0, 0.055, 0.0)])
    grasp = np.array([0.0, 0.0, np.pi / 2])  # a jaw 1.5 mm from the second bar: clear as seen
    robust = RobustVerifier(_Lifts(), [_Lifts()], RobustConfig(samples=1, shift_sigma=0.003, seed=1))
    moved = robust.perturbed(scene, [0], grasp, 0)
    assert moved.objects[1].y < 0.055 - 0.0015  # this seed moves the bar under the jaw
    r = robust.check(scene, [0], grasp)
    assert (
        not r.success
        and "open jaws start on an object or off the group in 1 of 1" in r.error
        and not r.lifted
    )
    assert (robust.base.calls, robust.variants[0].calls) == (0, 0)
    two = RobustVerifier(
        _Lifts(), [_Lifts(), _Lifts()], RobustConfig(samples=2, required=1, shift_sigma=0.003, seed=1)
    )
    assert two.check(scene, [0], grasp).success and two.base.calls == 1


def test_the_screen_keeps_the_open_jaws_as_far_from_a_neighbour_as_the_pose_error_reaches():
    """``screen`` worlds, geometry only, with no physics sample: a jaw 1.5 mm from a
    neighbour, each object's own error 4 mm (level 4's): some of 8 moved worlds put the bar
    under the jaw, so the grasp is refused and nothing is simulated; with the neighbour 40 mm
    away all 8 are clear and the nominal check alone decides. One world (``screen: 1``) can
    miss what 8 find."""
    grasp = np.array([0.0, 0.0, np.pi / 2])
    near = make_scene([("thick_bar", 0.0, 0.0, 0.0), ("thick_bar", 0.0, 0.055, 0.0)])
    far = make_scene([("thick_bar", 0.0, 0.0, 0.0), ("thick_bar", 0.0, 0.095, 0.0)])
    cfg = RobustConfig(screen=8, pose_sigma=0.004, yaw_sigma_deg=4)
    robust = RobustVerifier(_Lifts(), [], cfg)
    clear = robust.clear(near, [0], grasp, robust.offsets(near, [0], grasp, range(8))).tolist()
    assert 0 < sum(clear) < 8
    r = robust.check(near, [0], grasp)
    assert not r.success and f"in {8 - sum(clear)} of 8 perturbed worlds" in r.error and not r.lifted
    assert robust.base.calls == 0
    r = robust.check(far, [0], grasp)
    assert r.success and r.lifted == [0] and robust.base.calls == 1
    ones = [
        RobustVerifier(_Lifts(), [], replace(cfg, screen=1, seed=s)).check(near, [0], grasp) for s in range(8)
    ]
    assert any(r.success for r in ones) and not all(r.success for r in ones)
    with pytest.raises(MogError, match="planner.robust.screen"):
        RobustConfig(screen=65).check()


def test_the_screen_decides_all_its_worlds_at_once_as_the_conditions_do_on_each():
    """On a 33-object table at the paper's cell's perturbations, for grasps of one object and
    of it with its nearest neighbour at many poses: the screen's verdict in each of its worlds,
    all computed at once, is the conditions' collision and area checks (`evaluate_grasps`) on
    that world's moved scene."""
    from mog_drake.geometry import evaluate_grasps
    from mog_drake.scenes import cluttered_scene

    scene = cluttered_scene(np.random.default_rng(3))
    robust = RobustVerifier(
        _Lifts(), [], RobustConfig(screen=8, shift_sigma=0.003, pose_sigma=0.003, yaw_sigma_deg=3)
    )
    centers = scene.polygons().centers
    rng = np.random.default_rng(0)
    clear = 0
    for n in range(40):
        i = int(rng.integers(len(scene)))
        group = [i] if n % 2 else [i, int(np.argsort(np.linalg.norm(centers - centers[i], axis=1))[1])]
        grasp = np.append(centers[group].mean(axis=0), scene.objects[i].theta) + rng.normal(
            0, [0.01, 0.01, 0.5]
        )
        verdicts = robust.clear(scene, group, grasp, robust.offsets(scene, group, grasp, range(8)))
        for k in range(8):
            ev = evaluate_grasps(robust.perturbed(scene, group, grasp, k).polygons(), group, grasp[None])
            assert verdicts[k] == (ev.collision_free[0] and ev.area_ok[0])
        clear += verdicts.sum()
    assert 0 < clear < 320  # both verdicts met


def test_the_last_resort_first_takes_a_grasp_most_screen_worlds_keep_clear():
    """``relaxed_share``: a lone bar 4 mm of pose error (8 worlds) keeps out of the jaws in
    some worlds and not all, so no robust grasp. The last resort's first check is the screen
    at the share (the nominal check after it): a share at the bar's count of clear worlds
    passes, one world more refuses. In a decision, the relaxed pass finds the grasp before the
    nominal check alone; without the share the nominal check alone finds it."""
    from mog_drake.planning.config import PlannerSpec
    from mog_drake.planning.picking import next_pick
    from mog_drake.planning.planner import GraspConfig, GraspPlanner

    grasp = np.array([0.0, 0.0, np.pi / 2])
    near = make_scene([("thick_bar", 0.0, 0.0, 0.0), ("thick_bar", 0.0, 0.055, 0.0)])
    cfg = RobustConfig(screen=8, pose_sigma=0.004, yaw_sigma_deg=4)
    strict = RobustVerifier(_Lifts(), [], cfg)
    n = int(strict.clear(near, [0], grasp, strict.offsets(near, [0], grasp, range(8))).sum())
    assert 0 < n < 8 and not strict.check(near, [0], grasp).success and strict.relaxed() is None
    at = RobustVerifier(_Lifts(), [], replace(cfg, relaxed_share=(n - 0.5) / 8)).relaxed()
    assert at.clear_needed == n and at.check(near, [0], grasp).success and at.base.calls == 1
    above = RobustVerifier(_Lifts(), [], replace(cfg, relaxed_share=(n + 0.5) / 8)).relaxed()
    assert not above.check(near, [0], grasp).success and above.base.calls == 0

    lone = make_scene([("thick_bar", 0.0, 0.0, 0.3)])
    wide = RobustConfig(screen=8, pose_sigma=0.02, yaw_sigma_deg=10)  # no grasp clear in all 8
    for share, relaxed in ((0.1, True), (0.0, False)):
        planner = GraspPlanner(
            RobustVerifier(_Lifts(), [], replace(wide, relaxed_share=share)), GraspConfig("gp", max_physics=2)
        )
        d = next_pick(lone, planner, PlannerSpec())
        assert d.status == "grasp" and d.last_resort and d.relaxed == relaxed
    with pytest.raises(MogError, match="planner.robust.relaxed_share must be in"):
        RobustConfig(screen=8, relaxed_share=1.0).check()


def test_a_last_resort_grasp_replayed_from_memory_is_still_a_last_resort():
    """The lookahead remembers the grasp its decision found; when that was the last resort's
    (relaxed here), the next decision that replays it with no physics says so too, rather than
    passing it off as a robust grasp."""
    from mog_drake.planning.config import PlannerSpec
    from mog_drake.planning.decision import FailedGroup, around_group
    from mog_drake.planning.picking import next_pick
    from mog_drake.planning.planner import GraspConfig, GraspPlanner

    lone = make_scene([("thick_bar", 0.0, 0.0, 0.3)])
    wide = RobustConfig(screen=8, pose_sigma=0.02, yaw_sigma_deg=10, relaxed_share=0.1)
    planner = GraspPlanner(RobustVerifier(_Lifts(), [], wide), GraspConfig("gp", max_physics=2))
    d = next_pick(lone, planner, PlannerSpec())
    assert d.last_resort and d.relaxed and d.plans[-1].found_by == "relaxed"
    memory = (FailedGroup((0,), around_group(lone, (0,), planner.gripper), d.plans[-1]),)
    again = next_pick(lone, planner, PlannerSpec(), failures=memory)
    assert again.status == "grasp" and again.remembered == 1 and again.physics_checks == 0
    assert np.allclose(again.grasp, d.grasp) and again.last_resort and again.relaxed
