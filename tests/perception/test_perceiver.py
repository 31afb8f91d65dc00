"""Perceiver on rendered tables: accuracy, unrecognised blobs, toppled bars, the table beside the
bin, touching bars split, and the change check between two images."""

import math

import numpy as np
import pytest
from conftest import make_scene

from mog_drake.camera import camera_pose
from mog_drake.scenario import ClutteredScene, Scenario, SceneFile
from mog_drake.station import (
    MakeStation,
    render_still,
    rendered_intrinsics,
)


def test_perception_accuracy_on_a_rendered_isrr33_table(station33):
    """Median position <= 0.5 mm and yaw <= 1 deg, worst 1.5 mm and 3 deg, every object
    found, no extra object."""
    from mog_drake.perception import Perceiver, pose_errors

    sc, d, h = station33
    rgb, depth = render_still(sc, d)
    seen = Perceiver(table=sc.table, ignore=sc.perception_ignore()).perceive(
        rgb, depth, camera_pose(sc.camera), h.camera_intrinsics
    )
    errs = pose_errors(seen, h.scene)
    assert not [e for e in errs if e.get("extra")]
    assert seen.meta["unrecognised_blobs"] == 0  # every object point is explained
    matched = [e for e in errs if e["object"] is not None]
    assert all(e["position"] is not None for e in matched)  # all 33 found, right shapes
    pos = np.array([e["position"] for e in matched])
    yaw = np.degrees([e["yaw"] for e in matched])
    assert np.median(pos) <= 0.0005 and np.median(yaw) <= 1.0
    assert pos.max() <= 0.0015 and yaw.max() <= 3.0


def test_what_perception_cannot_recognise_is_outlined_and_grasped(tmp_path):
    """A shape perception does not know (here the trapezoid: it looks for pentagons only) is
    an unrecognised blob with its outline and top height; once nothing recognised is left,
    the planner grasps it as a prism of that outline, verified in physics like any grasp."""
    import shapely
    from conftest import make_scene

    from mog_drake.perception import Perceiver, PerceptionConfig
    from mog_drake.planning.picking import next_pick
    from mog_drake.scenes import Scene
    from mog_drake.systems.pick import make_planner

    truth = make_scene([("green_trapezoid", 0.05, -0.04, 0.4), ("blue_pentagon", -0.08, 0.06, 0.0)])
    truth.save(tmp_path / "unknown.yaml")
    sc = Scenario(scene=SceneFile(file=str(tmp_path / "unknown.yaml")))
    d, _ = MakeStation(sc)
    rgb, depth = render_still(sc, d)
    perceiver = Perceiver(
        table=sc.table, ignore=sc.perception_ignore(), config=PerceptionConfig(shapes=("blue_pentagon",))
    )
    seen = perceiver.perceive(rgb, depth, camera_pose(sc.camera), rendered_intrinsics(sc.camera))
    assert [o.shape for o in seen.objects] == ["blue_pentagon"]
    (blob,) = seen.meta["unrecognised"]
    true, got = shapely.Polygon(truth.polygon(0)), shapely.Polygon(blob["vertices"])
    assert got.intersection(true).area / got.union(true).area > 0.85
    assert abs(blob["top"] - truth.shape(0).height) < 0.003

    left = Scene([], seen.library, table=seen.table, meta=seen.meta)  # the pentagon was picked
    decision = next_pick(left, make_planner(sc), sc.planner)
    assert decision.status == "grasp" and decision.unrecognised and decision.expected == (0,)
    assert shapely.Polygon(truth.polygon(0)).distance(shapely.Point(decision.grasp[:2])) < 0.005


def test_perception_finds_toppled_bars_touching_upright_objects(tmp_path):
    """A bar knocked onto its side is the same box lying down: perception names it
    `thin_bar:on_side` (not an unrecognised blob), even pressed against upright objects."""
    from conftest import make_scene

    from mog_drake.perception import Perceiver, pose_errors

    truth = make_scene(
        [
            ("thin_bar:on_side", 0.0, 0.0, 0.3),
            # upright, 0.5 mm from the toppled one's long side
            ("thin_bar", -0.019 * math.sin(0.3), 0.019 * math.cos(0.3), 0.3),
            ("thick_bar:on_side", 0.07, -0.02, -0.5),
            ("large_hexagon", 0.07, 0.04, 0.0),
            ("thick_bar:on_end", -0.07, 0.05, 1.0),
        ]
    )
    truth.save(tmp_path / "toppled.yaml")
    sc = Scenario(scene=SceneFile(file=str(tmp_path / "toppled.yaml")))
    d, h = MakeStation(sc)
    rgb, depth = render_still(sc, d)
    seen = Perceiver(table=sc.table, ignore=sc.perception_ignore()).perceive(
        rgb, depth, camera_pose(sc.camera), rendered_intrinsics(sc.camera)
    )
    errs = pose_errors(seen, truth)
    assert sorted(o.shape for o in seen.objects) == sorted(o.shape for o in truth.objects)
    assert seen.meta["unrecognised_blobs"] == 0
    assert max(e["position"] for e in errs) <= 0.003
    assert max(math.degrees(e["yaw"]) for e in errs) <= 3.0


def test_perception_sees_beside_the_bin_and_leaves_out_what_the_arm_cannot_reach(tmp_path):
    """Objects pushed or dropped beside the bin (y ~ 0.36 m) are in view and planned for; one
    in the table's far corner, beyond the arm's reach, is not reported (it is counted)."""
    from conftest import make_scene

    from mog_drake.perception import Perceiver, pose_errors

    truth = make_scene(
        [
            ("red_triangle", 0.06, 0.36, 0.4),  # beside the bin
            ("thick_bar", -0.05, -0.37, 1.2),  # the far side
            ("large_hexagon", 0.0, 0.0, 0.0),
            ("small_yellow_cube", 0.28, 0.37, 0.3),  # in view, 0.87 m from the base
        ],
        table=(-0.3, 0.3, -0.4, 0.4),
    )
    truth.save(tmp_path / "edges.yaml")
    sc = Scenario(scene=SceneFile(file=str(tmp_path / "edges.yaml")))
    d, h = MakeStation(sc)
    rgb, depth = render_still(sc, d)
    args = (rgb, depth, camera_pose(sc.camera), rendered_intrinsics(sc.camera))
    everything = Perceiver(table=sc.table, ignore=sc.perception_ignore()).perceive(*args)
    assert sorted(o.shape for o in everything.objects) == sorted(o.shape for o in truth.objects)
    seen = sc.perceiver().perceive(*args)
    assert sorted(o.shape for o in seen.objects) == ["large_hexagon", "red_triangle", "thick_bar"]
    assert seen.meta["beyond_reach"] == 1 and seen.meta["unrecognised_blobs"] == 0
    errs = [e["position"] for e in pose_errors(seen, truth) if e["position"] is not None]
    assert len(errs) == 3 and max(errs) <= 0.003


@pytest.mark.parametrize("seed, yaw_deg", [(0, 3.0), (3, 3.0), (5, 5.0)])
def test_touching_bars_are_split_right(seed, yaw_deg):
    """On these tables two touching bars of one kind (one colour, one height) form one
    cluster. On tables 0 and 3 (thin bars) one k-means seeding split it wrongly (12.7 mm,
    23 deg). On table 5 two thick bars lie side by side, and every k-means seeding split the
    blob across both bars (12.7 mm, 47 deg); median splits along 6 directions find the line
    between them (3.8 deg off on one of the two)."""
    from mog_drake.perception import pose_errors
    from mog_drake.scenes import cluttered_scene

    scene = cluttered_scene(np.random.default_rng(seed))
    sc = Scenario(scene=ClutteredScene(seed=seed))
    d, h = MakeStation(sc, scene)
    rgb, depth = render_still(sc, d)
    seen = sc.perceiver().perceive(rgb, depth, camera_pose(sc.camera), rendered_intrinsics(sc.camera))
    errs = pose_errors(seen, scene)
    assert all(e["position"] is not None for e in errs) and seen.meta["unrecognised_blobs"] == 0
    assert max(e["position"] for e in errs) <= 0.003
    assert max(math.degrees(e["yaw"]) for e in errs) <= yaw_deg


@pytest.mark.parametrize(
    "shape, n, gap, along, th",
    [("thick_bar", 3, 0.002, 0.01, 1.5), ("thin_bar", 5, 0.0005, 0.0, 2.3)],
)
def test_bars_in_a_row_are_counted_on_the_paper_cells_depth(shape, n, gap, along, th):
    """Upright bars side by side ``gap`` apart, every other one ``along`` its length, seen
    through the paper's cell's depth (noise, holes, flying pixels; four draws). Three thick
    bars' tops show about 2.45 bars' area, which rounds to two: split in two, a bar was
    missed in every draw. Perception tries one more instance when a split leaves a top's
    worth unexplained; five thin bars are where one more, taken on its score alone, was
    invented between two real ones in two draws (`instances.SHARED`)."""
    from dataclasses import replace

    from mog_drake.scenario import load_scenario
    from mog_drake.sim.realism import depth_artefacts

    base = load_scenario("models/paper_cell.yaml")
    width = {"thin_bar": 0.007, "thick_bar": 0.012}[shape]
    across, length = np.array([-math.sin(th), math.cos(th)]), np.array([math.cos(th), math.sin(th)])
    row = [np.array([0.02, -0.03]) + k * (width + gap) * across + (k % 2) * along * length for k in range(n)]
    scene = make_scene([(shape, *p, th) for p in row])
    quiet = replace(base.realism, depth_noise=0.0, depth_holes=0.0, flying_pixels=0.0)
    sc = replace(base, realism=quiet)
    d, h = MakeStation(sc, scene)
    ctx = d.CreateDefaultContext()
    h.seen_poses(0.0).update(ctx)
    rgb, clean = (np.array(a) for a in render_still(sc, d, ctx))
    for k in range(4):
        world = base.realism.draw(k, 1)
        depth = depth_artefacts(
            clean,
            rgb,
            world.depth_rng(0.0),
            noise=base.realism.depth_noise,
            holes=world.depth_holes,
            flying=world.flying_pixels,
            fx=h.camera_intrinsics[0],
        )
        seen = base.perceiver().perceive(rgb, depth, camera_pose(base.camera), h.camera_intrinsics, seed=k)
        assert [o.shape for o in seen.objects] == [shape] * n


def test_the_change_check_sees_moved_and_uncovered_objects_not_a_millimetre(tmp_path):
    """Perceiver.changed_pixels between two depth images: the same table gives 0; a hexagon
    moved 1 mm gives 0 (its outline shifts by a pixel: no new plan for that); moved 6 mm,
    hundreds; an object found where the first image saw the arm over the table counts too."""
    from mog_drake.camera import camera_pose
    from mog_drake.station import MakeStation, render_still

    def depth_of(x):
        scene = make_scene([("large_hexagon", x, 0.05, 0.3), ("blue_quad", -0.1, -0.1, 0.0)])
        scene.save(tmp_path / "t.yaml")
        sc = Scenario(scene=SceneFile(file=str(tmp_path / "t.yaml")))
        d, h = MakeStation(sc)
        return sc, h, np.array(render_still(sc, d)[1])

    sc, h, d0 = depth_of(0.05)
    perceiver = sc.perceiver()
    args = (camera_pose(sc.camera), h.camera_intrinsics)
    assert perceiver.changed_pixels(d0, d0.copy(), *args) == 0
    assert perceiver.changed_pixels(d0, depth_of(0.051)[2], *args) == 0
    assert perceiver.changed_pixels(d0, depth_of(0.056)[2], *args) > 100
    armed = d0.copy()
    rows, cols = np.nonzero(np.abs(d0 - 0.77) < 0.002)  # the hexagon's top (0.03 m high)
    armed[rows, cols] = 0.3  # something 0.5 m above the table hid it
    assert perceiver.changed_pixels(armed, d0, *args) > 100
    assert perceiver.changed_pixels(armed, d0, *args, still=True) == 0  # not a motion: unknown


def test_the_change_check_on_a_miscalibrated_camera_sees_no_change_where_the_arm_was(tmp_path):
    """The table at rest, seen first with the arm over the bin's corner of the table (a patch of
    depth 0.3 m) and then without it, on a camera whose pose is off by 3 mm and 0.15 deg (the
    paper's cell): the table there is 4-5 mm high and the bin's outer walls move by millimetres.
    With ``fit_table`` (heights from the table's plane) and the bin's keep-out margin ignored,
    nothing changed, and the hexagon found where the arm hid it did; heights from z = 0 take
    the table's patch for an object that appeared."""
    from dataclasses import replace

    from pydrake.math import RigidTransform, RollPitchYaw

    from mog_drake.station import MakeStation, render_still

    scene = make_scene([("large_hexagon", 0.05, 0.05, 0.3), ("blue_quad", -0.1, -0.1, 0.0)])
    scene.save(tmp_path / "t.yaml")
    sc = Scenario(scene=SceneFile(file=str(tmp_path / "t.yaml")))
    d, h = MakeStation(sc)
    after = np.array(render_still(sc, d)[1])
    before = after.copy()
    before[: after.shape[0] // 3, after.shape[1] * 2 // 3 :] = 0.3  # the bin is at the top right
    error = RigidTransform(RollPitchYaw(np.radians([0.1, 0.15, 0.0])), [0.003, -0.002, -0.003])
    X_WC = camera_pose(sc.camera) @ error.GetAsMatrix4()
    args = (before, after, X_WC, h.camera_intrinsics)
    fitted = replace(sc, perception=replace(sc.perception, fit_table=True)).perceiver()
    assert fitted.changed_pixels(*args) == 0
    assert sc.perceiver().changed_pixels(*args) > 40  # heights from z = 0: a retake for nothing
    armed = after.copy()  # and an object where the arm was is still seen
    rows, cols = np.nonzero(np.abs(after - 0.77) < 0.002)  # the hexagon's top (0.03 m high)
    armed[rows, cols] = 0.3
    assert fitted.changed_pixels(armed, after, X_WC, h.camera_intrinsics) > 100
