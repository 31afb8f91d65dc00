"""Configuration as data: everything a pick-and-place run depends on, one dataclass per concern.

Each part's own config is nested as it is and passed straight to its builder: Drake's
`MultibodyPlantConfig` (inside `ContactConfig`), `SimulatorConfig`, `CameraConfig` and
`VisualizationConfig`, and the project's `PlannerSpec`, `PerceptionConfig`, `MotionConfig`,
`ControllerConfig`, `GripperPhysics`. Variants are chosen by YAML tags, as in Drake's
hardware_sim: ``scene: !RowScene {row_class: 3}``, ``hardware: {camera: !ReplaySource {dir:
frames}}``. `load_scenario` reads a YAML file over the defaults with `yaml_load_typed`;
`models/scenario.yaml` is generated from the defaults (``python -m mog_drake.scenario``) and
lists every setting.

World frame = table frame: origin at the centre of the table top, z up.
"""

import dataclasses
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Union

import numpy as np
from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed
from pydrake.systems.analysis import SimulatorConfig
from pydrake.systems.sensors import CameraConfig
from pydrake.visualization import VisualizationConfig

from mog_drake.camera import check_camera, default_camera
from mog_drake.config import ControllerConfig, LatencyConfig, MotionConfig, box_bounds, in_range
from mog_drake.errors import MogError
from mog_drake.files import model_path, read_text
from mog_drake.hardware.config import HardwareSpec
from mog_drake.perception import PerceptionConfig
from mog_drake.planning.config import PlannerSpec
from mog_drake.scenes.library import check_yaml
from mog_drake.sim.models import ContactConfig, GripperPhysics
from mog_drake.sim.realism import RealismConfig
from mog_drake.sim.verifier_config import VerifierConfig

SCENARIO_YAML = model_path("scenario.yaml")
# A scenario sets a few hundred values (models/scenario.yaml, every setting: about 250); many
# more is a mistake that the typed loader would take seconds per 100 kB to refuse.
MAX_SCENARIO_VALUES = 5000
# m kept between the planner's open jaws (the authors' idealised plates, 95 mm across their
# outer faces) and the bin's outer walls: room for the real fingers' links around the pads
# and for where a grasp lands (perception's pose error is about 1 mm, the arm's a few).
KEEP_OUT_MARGIN = 0.01


# --- the objects on the table: one of three sources, chosen by tag -------------------------
@dataclass
class ClutteredScene:
    """A seeded cluttered table drawn from an inventory (`scenes.cluttered_scene`)."""

    seed: int = 0
    inventory: str = "isrr33"
    n_objects: int = 0  # 0: the whole inventory

    def check(self) -> None:
        if not 0 <= self.seed < 2**63:
            raise MogError(f"scene.seed must be a whole number >= 0, got {self.seed}")
        if self.n_objects < 0:
            raise MogError(
                f"scene.n_objects must be at least 0 (0: the whole inventory), got {self.n_objects}"
            )


@dataclass
class RowScene:
    """One of the paper's row classes (`scenes.row_scene`), seeded."""

    seed: int = 0
    row_class: int = 3

    def check(self) -> None:
        from mog_drake.scenes import ROW_CLASSES

        if not 0 <= self.seed < 2**63:
            raise MogError(f"scene.seed must be a whole number >= 0, got {self.seed}")
        if self.row_class not in ROW_CLASSES:
            raise MogError(f"scene.row_class must be one of {sorted(ROW_CLASSES)}, got {self.row_class}")


@dataclass
class SceneFile:
    """A scene YAML file (`mog-drake scene generate` writes them)."""

    file: str = ""

    def check(self) -> None:
        if not self.file.strip():
            raise MogError("scene.file must name a scene file (!SceneFile {file: my_scene.yaml})")


SceneSource = Union[ClutteredScene, RowScene, SceneFile]  # noqa: UP007
# (No "from __future__ import annotations" here: yaml_dump_typed reads the field types.)


@dataclass
class RobotSpec:
    # x, y, yaw of the UR5 base; yaw pi turns the DH zero pose (arm along -x) towards the table.
    base: list[float] = field(default_factory=lambda: [-0.50, 0.0, 3.14159265])
    # Observe pose (rad): the palm at (-0.33, 0, 0.35) m, outside the camera's view.
    home: list[float] = field(default_factory=lambda: [-0.692, -2.413, 1.965, -1.122, -1.573, -2.262])
    max_joint_speed: float = 3.14  # rad/s (the UR5 does 180 deg/s)
    max_joint_acceleration: float = 3.14  # rad/s^2
    # Horizontal distance from the base's axis within which the arm reaches a top-down grasp at
    # the table (m). IK reaches 0.86 m in every direction over the table; 2 cm are kept for a
    # grasp centred off its object. Perception reports no object whose centre lies beyond it.
    reach: float = 0.84
    kp: float = 4000.0
    kd: float = 400.0

    def check(self) -> None:
        if len(self.base) != 3 or len(self.home) != 6:
            raise MogError("robot.base must be [x, y, yaw] and robot.home six joint angles")
        in_range(self.reach, "robot.reach", 0, 2.0)
        in_range(self.max_joint_speed, "robot.max_joint_speed", 0, 2 * math.pi)
        in_range(self.max_joint_acceleration, "robot.max_joint_acceleration", 0, 40.0)
        in_range(self.kp, "robot.kp", 0, 1e7)
        in_range(self.kd, "robot.kd", 0, 1e6, lo_open=False)


@dataclass
class BinSpec:
    center: list[float] = field(default_factory=lambda: [-0.25, 0.38])
    inner: list[float] = field(default_factory=lambda: [0.24, 0.18])
    depth: float = 0.10
    wall: float = 0.01

    def check(self) -> None:
        if len(self.center) != 2 or len(self.inner) != 2 or min(self.inner) <= 0:
            raise MogError("bin.center must be [x, y] and bin.inner two positive sizes")
        in_range(self.depth, "bin.depth", 0, 1.0)
        in_range(self.wall, "bin.wall", 0, 0.2)

    def footprint(self, margin: float = 0.0) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) of the bin's outside walls, grown by ``margin``."""
        hx, hy = self.inner[0] / 2 + self.wall + margin, self.inner[1] / 2 + self.wall + margin
        cx, cy = self.center
        return (cx - hx, cx + hx, cy - hy, cy + hy)


@dataclass
class Scenario:
    """Everything a pick-and-place run depends on. Defaults run with no file at all."""

    scene: SceneSource = field(default_factory=ClutteredScene)
    robot: RobotSpec = field(default_factory=RobotSpec)
    bin: BinSpec = field(default_factory=BinSpec)
    camera: CameraConfig = field(default_factory=default_camera)
    # The world's contact (`ContactConfig`: a real table's friction, triangle contact surfaces).
    contact: ContactConfig = field(default_factory=ContactConfig)
    # The physics check of the picking planner (`VerifierConfig`).
    verifier: VerifierConfig = field(default_factory=VerifierConfig)
    # The jaws, coupled as on the 2F-85, in the station and in the planner's check alike.
    gripper: GripperPhysics = field(default_factory=GripperPhysics)
    planner: PlannerSpec = field(default_factory=PlannerSpec)
    perception: PerceptionConfig = field(default_factory=PerceptionConfig)
    motion: MotionConfig = field(default_factory=MotionConfig)
    controller: ControllerConfig = field(default_factory=ControllerConfig)
    # How long perception and planning take in simulated time: each job's measured wall time,
    # or fixed times per stage (runs comparable across machines).
    latency: LatencyConfig = field(default_factory=LatencyConfig)
    # The simulated station's Simulator. Its target_realtime_rate stays 0: a real-time run is
    # paced by the wall clock without catch-up (systems.pacer.WallClockPacer).
    simulator: SimulatorConfig = field(default_factory=SimulatorConfig)
    # Meshcat (--meshcat, --record): the illustration geometry only.
    visualization: VisualizationConfig = field(
        default_factory=lambda: VisualizationConfig(
            publish_proximity=False, publish_contacts=False, enable_alpha_sliders=False
        )
    )
    # The perceived table (xmin, xmax, ymin, ymax): where perception looks for objects (within
    # the arm's reach, robot.reach). The camera sees all of it; the table under it is larger.
    table: list[float] = field(default_factory=lambda: [-0.30, 0.30, -0.40, 0.40])
    time_limit: float = 600.0  # s of simulated robot time
    # The simulated station: objects at rest out of reach of the gripper and of anything
    # moving leave the physics until something could reach them (`station.speed`).
    sleep: bool = True
    # How the simulated world differs from the planner's model (`mog_drake.sim.realism`):
    # nothing by default; models/realistic.yaml sets a real cell's calibration, sensing and
    # parameter errors.
    realism: RealismConfig = field(default_factory=RealismConfig)
    hardware: HardwareSpec = field(default_factory=HardwareSpec)

    def perception_ignore(self) -> list[tuple[float, float, float, float]]:
        """Regions where perception looks for no object: the bin and KEEP_OUT_MARGIN around it
        (where no grasp goes). The camera sees the outside of the bin's walls, 0.1 m tall: a
        calibration off by a few millimetres or a tenth of a degree moves them by as much on
        the table, where the check at the next image took them for an object that appeared
        where the arm was."""
        return [self.bin.footprint(KEEP_OUT_MARGIN)]

    def keep_out(self) -> list[tuple[float, float, float, float]]:
        """Regions the planner's jaws and pushes stay out of: the bin's walls and KEEP_OUT_MARGIN
        around them. The bin is taller than the jaws' reach down to the table, and the physics
        check does not model it: a grasp whose open jaws would land on its wall passes that
        check and then fails on the robot, again and again."""
        return [self.bin.footprint(KEEP_OUT_MARGIN)]

    def perception_reach(self) -> tuple[float, float, float]:
        """(x, y, radius): the disc about the robot's base within which the arm reaches."""
        bx, by, _ = self.robot.base
        return (float(bx), float(by), float(self.robot.reach))

    def perceiver(self, library=None):
        """A Perceiver of this scenario's perceived table: its ignored regions and the arm's
        reach (what the Perception system uses)."""
        from mog_drake.perception import Perceiver

        return Perceiver(
            library,
            config=self.perception,
            table=self.table,
            ignore=self.perception_ignore(),
            reach=self.perception_reach(),
        )


# --- loading ----------------------------------------------------------------------------------
def scenario_path(path: str) -> Path:
    """``path``, or where it names a scenario shipped in ``models/`` by its bare name (no
    such file here, no folder: ``realistic`` or ``realistic.yaml``), that file."""
    p = Path(path)
    if not p.exists() and str(p.parent) == "." and p.suffix in ("", ".yaml"):
        shipped = model_path(p.stem + ".yaml")
        if shipped.is_file():
            return shipped
    return p


def load_scenario(path: str | None = None) -> Scenario:
    """The default scenario, overridden by a YAML file (keys as the dataclass fields), or by
    a scenario shipped in ``models/``, named (`scenario_path`)."""
    if not path:
        return Scenario()
    return scenario_from_text(read_text(scenario_path(path), "scenario file"), str(path))


def with_overrides(sc: Scenario, where: str = "", **given) -> Scenario:
    """``sc`` with a run's overrides (None: keep): ``seed`` (the scene's and the planner's),
    ``mode``, ``objects`` (a cluttered table), ``time_limit``, and on a hardware scenario only
    ``robot_ip`` and ``dry_run``. ``where`` names ``sc`` in errors."""
    seed, mode, objects = given.get("seed"), given.get("mode"), given.get("objects")
    if seed is not None:
        sc.scene = replace(sc.scene, seed=seed) if hasattr(sc.scene, "seed") else sc.scene
        sc.planner = replace(sc.planner, seed=seed)
    if mode:
        sc.planner = replace(sc.planner, mode=mode)
    if objects:
        if not hasattr(sc.scene, "n_objects"):
            raise MogError("--objects applies to a cluttered table (scene: !ClutteredScene)")
        sc.scene = replace(sc.scene, n_objects=objects)
    sc.time_limit = given.get("time_limit") or sc.time_limit
    for key, flag in (("robot_ip", "--robot-ip"), ("dry_run", "--dry-run")):
        if not given.get(key):
            continue
        if not sc.hardware.enabled:
            raise MogError(
                f"{flag} applies to a hardware scenario (hardware.enabled: true, e.g. models/hardware.yaml);"
                f" {where or 'the default scenario'} is simulated"
            )
        sc.hardware = replace(sc.hardware, **{key: given[key]})
    return sc


def scenario_from_text(text: str, where: str = "scenario") -> Scenario:
    """A scenario from YAML text (a file's contents), checked like ``load_scenario``."""
    check_yaml(text, where, max_values=MAX_SCENARIO_VALUES)
    if _empty(text):  # no keys (or comments only): every setting keeps its default
        return Scenario()
    try:
        sc = yaml_load_typed(schema=Scenario, data=text, defaults=Scenario())
    except Exception as e:  # Drake's loader raises RuntimeError, TypeError, ValueError, yaml's own
        lines = [ln.strip() for ln in str(e).splitlines() if ln.strip()]
        key = _failing_key(text)
        raise MogError(
            f"{where}: {key + ': ' if key else ''}{lines[0] if lines else type(e).__name__}"
        ) from None
    try:
        check_scenario(sc)
    except MogError as e:
        raise MogError(f"{where}: {e}") from None
    return sc


def _empty(text: str) -> bool:
    """Whether YAML ``text`` holds no document, or only a null one."""
    import yaml

    try:
        return all(
            doc is None for doc in yaml.load_all(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
        )
    except yaml.YAMLError:
        return False  # the typed loader names what is wrong


def _failing_key(text: str) -> str:
    """The dotted key whose value the typed loader refuses (its own errors do not name it):
    each mapping entry is loaded alone, tags kept, descending into the one that fails."""
    import yaml

    def loads(node) -> bool:
        try:
            yaml_load_typed(schema=Scenario, data=yaml.serialize(node), defaults=Scenario())
            return True
        except Exception:
            return False

    try:
        root = yaml.compose(text)
    except yaml.YAMLError:
        return ""
    path, wrap, node = [], (lambda n: n), root
    while isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            alone = yaml.MappingNode(node.tag, [(k, v)])
            if not loads(wrap(alone)):
                path.append(str(k.value))
                wrap = (lambda w, t, kk: lambda n: w(yaml.MappingNode(t, [(kk, n)])))(wrap, node.tag, k)
                node = v
                break
        else:
            break
    return ".".join(path)


def scenario_yaml(scenario: Scenario | None = None) -> str:
    """The scenario as YAML (every setting, variants tagged)."""
    return yaml_dump_typed(scenario if scenario is not None else Scenario())


def _finite_leaves(obj, path: str = ""):
    """(key path, value) of every number in a config tree (dataclasses, Drake structs, lists)."""
    if isinstance(obj, bool) or obj is None or isinstance(obj, str):
        return
    if isinstance(obj, (int, float)):
        yield path, obj
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            yield from _finite_leaves(v, f"{path}[{i}]")
    elif isinstance(obj, np.ndarray):
        for i, v in enumerate(obj.ravel()):
            yield f"{path}[{i}]", float(v)
    elif dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            yield from _finite_leaves(getattr(obj, f.name), f"{path}.{f.name}" if path else f.name)
    elif hasattr(type(obj), "__fields__"):  # a Drake config struct
        for f in type(obj).__fields__:
            yield from _finite_leaves(getattr(obj, f.name), f"{path}.{f.name}" if path else f.name)


def check_scenario(sc: Scenario) -> None:
    """Refuses, at load, a setting that would fail only once the robot runs, or crash in the
    physics: every number finite, and each in the range it means something in (the key named).
    Each section checks its own keys; here only what spans sections."""
    for key, v in _finite_leaves(sc):
        if not math.isfinite(v):
            raise MogError(f"{key} must be a finite number, got {v!r}")
    sc.scene.check()
    sc.robot.check()
    sc.bin.check()
    check_camera(sc.camera)
    sc.contact.check("contact")
    sc.verifier.check()
    sc.gripper.check()
    sc.planner.check()
    sc.perception.check()
    sc.motion.check()
    sc.controller.check()
    sc.latency.check()
    sc.realism.check()
    sc.hardware.check()
    in_range(sc.time_limit, "time_limit", 0, 1e6)
    box_bounds(sc.table, "table", 4)
    if any(abs(v) > 10 for v in sc.table):
        raise MogError(f"table must lie within 10 m of the origin, got {list(sc.table)}")
    if sc.realism.enabled and sc.hardware.enabled:
        raise MogError("realism applies to the simulated cell; a hardware run meets the real one")
    if sc.hardware.enabled and sc.robot.max_joint_speed > sc.hardware.max_joint_speed:
        # The driver refuses any target faster than its limit: such a run would fault at its
        # first motion, with the arm already under way.
        raise MogError(
            f"robot.max_joint_speed {sc.robot.max_joint_speed:g} rad/s plans faster than "
            f"hardware.max_joint_speed {sc.hardware.max_joint_speed:g} rad/s allows: lower the first"
        )


HEADER = """\
# The default pick-and-place scenario: every setting, generated from mog_drake.scenario.Scenario
# (python -m mog_drake.scenario); SI units. Copy it, keep what you change, run:
#   mog-drake pick --scenario my.yaml
# Omitted keys keep these values. Variants are chosen by YAML tag:
#   scene: !ClutteredScene {...} (the default, written untagged), !RowScene {...}, !SceneFile {file: ...}
#   hardware: {camera: !RealSenseSource {...} (the default), !ReplaySource {dir: ...}}
"""

if __name__ == "__main__":
    SCENARIO_YAML.write_text(HEADER + scenario_yaml())
    print(f"wrote {SCENARIO_YAML}")
